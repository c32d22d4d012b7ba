"""tf2_ros's broadcasters publish TFMessages on /tf and latched on /tf_static."""


def transform(child: str, x: float = 0.0):
    from geometry_msgs.msg import TransformStamped
    stamped = TransformStamped(child_frame_id=child)
    stamped.header.frame_id = 'base_link'
    stamped.transform.translation.x = x
    return stamped


def test_transform_broadcaster_publishes_on_tf_with_depth_100(rclpy, runtime):
    from tf2_ros import TransformBroadcaster
    node = rclpy.create_node('bridge')
    broadcaster = TransformBroadcaster(node)
    assert broadcaster.pub_tf.topic_name == '/tf' and broadcaster.pub_tf.qos_profile.depth == 100
    seen = []
    runtime.add_tap(lambda topic, msg, t_ns: seen.append((topic, msg)))
    broadcaster.sendTransform(transform('base_link'))
    broadcaster.sendTransform([transform('a'), transform('b')])
    assert [(topic, [t.child_frame_id for t in msg.transforms]) for topic, msg in seen] == [
        ('/tf', ['base_link']), ('/tf', ['a', 'b'])]


def test_static_broadcaster_latches_every_child_frame_for_late_subscribers(rclpy, runtime):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from tf2_msgs.msg import TFMessage
    from tf2_ros import StaticTransformBroadcaster
    node = rclpy.create_node('bridge')
    broadcaster = StaticTransformBroadcaster(node)
    broadcaster.sendTransform(transform('laser', 0.1))
    broadcaster.sendTransform(transform('camera'))
    broadcaster.sendTransform(transform('laser', 0.2))
    received = []
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rclpy.create_node('late').create_subscription(TFMessage, '/tf_static', received.append,
                                                  latched)
    runtime.run_until(0)
    assert len(received) == 1
    assert [(t.child_frame_id, t.transform.translation.x) for t in received[0].transforms] == [
        ('laser', 0.2), ('camera', 0.0)]

"""Topic and node names resolve, remap and validate the way rcl does it."""

import pytest


@pytest.mark.parametrize('namespace, topic, resolved', [
    (None, 'scan', '/scan'), ('/', '/scan', '/scan'), ('robot1', 'scan', '/robot1/scan'),
    ('/robot1', '/scan', '/scan'), ('/robot1', '~/status', '/robot1/wall_follow/status'),
    (None, '~/status', '/wall_follow/status'), ('/a/b', '{node}/debug', '/a/b/wall_follow/debug'),
])
def test_topic_names_expand_against_the_node(rclpy, namespace, topic, resolved):
    node = rclpy.create_node('wall_follow', namespace=namespace)
    assert node.resolve_topic_name(topic) == resolved


@pytest.mark.parametrize('topic', ['', 'scan scan', '2scan', 'scan/', 'a//b', 'a~b'])
def test_invalid_topic_names_raise_rclpy_exception(rclpy, topic):
    from rclpy.exceptions import InvalidTopicNameException
    node = rclpy.create_node('n')
    from std_msgs.msg import Int32
    with pytest.raises(InvalidTopicNameException):
        node.create_publisher(Int32, topic, 10)


@pytest.mark.parametrize('name', ['', 'my-node', '1node', 'a/b'])
def test_invalid_node_names_raise_rclpy_exception(rclpy, name):
    from rclpy.exceptions import InvalidNodeNameException
    with pytest.raises(InvalidNodeNameException):
        rclpy.create_node(name)


def test_remaps_rename_topics_node_and_namespace(runtime):
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Int32
    rclpy.init(args=['--ros-args', '-r', 'scan:=base_scan', '-r', 'other:__node:=ignored'])
    node = Node('driver', cli_args=['--ros-args', '-r', '__node:=renamed', '-r',
                                    '__ns:=/robot2'])
    assert (node.get_name(), node.get_namespace()) == ('renamed', '/robot2')
    assert node.get_fully_qualified_name() == '/robot2/renamed'
    assert node.create_publisher(Int32, 'scan', 10).topic_name == '/robot2/base_scan'
    assert node.get_logger().name == 'robot2.renamed'

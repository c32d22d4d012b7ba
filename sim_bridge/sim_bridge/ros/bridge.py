"""
The simulator as a ROS 2 node: it stands in for Gazebo and its ROS bridge in the lab.

Publishes ``scan`` (sensor_msgs/LaserScan) at the lidar's ``update_rate``, in the lidar's frame;
the odometry (nav_msgs/Odometry) on the drive plugin's odometry topic (``odom``) with TF
odom -> base, static TF base -> lidar frame, ``clock`` (rosgraph_msgs/Clock) and
``collisions`` (geometry_msgs/PointStamped); obeys the drive plugin's command topic
(``cmd_vel``) in the type its publishers use: geometry_msgs/Twist, or TwistStamped as
TurtleBot3's Jazzy packages publish it. The bridge subscribes once a publisher shows on the ROS
graph, with that publisher's type (a node of another type in the same process could not even
create its publisher otherwise); ``cmd_vel_stamped`` true or false fixes the type instead.
Publishers of both types at once are an error naming them. As Gazebo's DiffDrive does, it
keeps the last command until the next one (``cmd_vel_timeout`` > 0 stops the robot after that
many s without one). Live, a timer on the steady clock steps
the physics at ``physics_rate`` (Hz), paced at ``real_time_factor`` x wall-clock speed; the
other nodes run with ``use_sim_time:=true``. Stepped (``SimBridge(stepped=True)``), the runner
calls :meth:`SimBridge.step` itself, as Gazebo's lockstep does with its clients.

The drive follows the robot model's diff-drive plugin (``Model.drive``: limits, topics,
frames, odometry rate, TF); what it leaves unset is Gazebo's default. Precedence: a parameter
given to the node (params file, ``-p``, launch) wins over the plugin, which wins over the
kit's default; each such parameter is declared with the plugin's value as its default.

TF needs ``tf2_ros``, which a ROS 2 installation has and PyPI does not: without it the bridge
says so once and publishes everything else.
"""

from array import array
from functools import partial
import math
import sys

from geometry_msgs.msg import PointStamped, TransformStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import rclpy
from rclpy.clock import Clock as RclpyClock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan

try:
    from tf2_ros import StaticTransformBroadcaster, TransformBroadcaster
except ImportError:  # tf2_ros is part of a ROS 2 installation, not of the PyPI wheels
    StaticTransformBroadcaster = TransformBroadcaster = None

from sim_bridge.common.message_types import message_type_name
from sim_bridge.common.text import one_line
from sim_bridge.ros.rviz import publish_scene
from sim_bridge.simulation.geometry import quaternion_from_euler
from sim_bridge.simulation.robot import DiffDriveConfig, DriveLimits, pose_from
from sim_bridge.simulation.sdf_frames import relative_pose
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.update_schedule import NANOSECONDS_PER_SECOND, UpdateSchedule
from sim_bridge.simulation.world import World

#: Hz, when neither the world (its physics step) nor the physics_rate parameter sets one: ten
#: times a lab lidar's rate (Gazebo's own default step, 1 ms, would be 1000 Hz).
DEFAULT_PHYSICS_RATE = 100.0
#: Simulated seconds between looks at the command topic's publishers on the ROS graph: until
#: the bridge subscribes, and after (when a second type is an error).
COMMAND_GRAPH_CHECK_S = (0.1, 1.0)
COMMAND_TYPES = {'geometry_msgs/msg/Twist': Twist, 'geometry_msgs/msg/TwistStamped': TwistStamped}
ODOMETRY_TYPE = message_type_name(Odometry)
NO_TF_WARNING = ('tf2_ros is not installed (it comes with a ROS 2 installation, not from PyPI): '
                 'publishing no TF (odom -> base, base -> lidar frame); odometry, scans and '
                 '/clock are published as usual')


def float32_array(values: np.ndarray) -> array:
    """
    Return ``values`` as the ``array('f')`` rosidl stores a float32 sequence field in.

    Rounded by numpy in one pass: handed a numpy array, rosidl's setter converts it one
    element at a time (about 40 us for 1081 beams).
    """
    return array('f', np.asarray(values, dtype=np.float32).tobytes())


def relative(topic: str) -> str:
    """Return a plugin's topic as a relative ROS name: in the node's namespace, remappable."""
    return topic.lstrip('/')


def command_type(topic: str, publishers: dict[str, list[str]]) -> tuple[type | None, str]:
    """
    Return (the message type to subscribe to ``topic`` with, an error line) for its publishers.

    ``publishers`` maps each ROS type name on the topic to the names of the nodes publishing
    it. (None, '') while none publishes Twist or TwistStamped; one type: (its class, '');
    both: (None, the error naming each type's publishers).
    """
    kinds = {name: nodes for name, nodes in publishers.items() if name in COMMAND_TYPES}
    if len(kinds) > 1:
        who = '; '.join(f"{', '.join(nodes)} publish {name.rpartition('/')[2]}"
                        for name, nodes in kinds.items())
        return None, (f'{topic} has publishers of both command types ({who}): the simulator '
                      'takes one; publish Twist or TwistStamped from every node')
    return next((COMMAND_TYPES[name] for name in kinds), None), ''


#: What SimBridge's start raises for bad input (a parameter of the wrong type or value, an
#: unknown world, a world or robot file it cannot load): its message says what, in one line.
START_ERRORS = (OSError, ValueError, LookupError, ParameterException)


class SimBridge(Node):
    """
    Step the simulator and bridge it to ROS topics.

    ``stepped``: create no timer; whoever drives the bridge calls :meth:`step`. Other keyword
    arguments go to rclpy's Node.
    """

    def __init__(self, *, stepped: bool = False, **kwargs):
        super().__init__('sim_bridge', **kwargs)
        world = self.load_world()
        # What the world's files ask for and the simulator does not do, said once, at start.
        if world.ignored:
            self.get_logger().info(world.ignored)
        world_step_s = world.physics_step_s
        # The robot model's diff-drive plugin gives the drive's defaults, Gazebo's own where
        # the plugin leaves something unset (a robot without one: DiffDriveConfig's); a
        # parameter given to the node (params file, -p, launch) overrides it.
        drive = world.robot.drive or DiffDriveConfig()
        self.frames = self.declare_frames(world, drive)
        limits = DriveLimits(**{name: self.declare_parameter(name, float(default)).value
                                for name, default in vars(drive.limits).items()})
        # Every other parameter is read before the simulator (a pybullet client) exists, so a
        # bad one cannot leave a client behind.
        physics_rate = self.rate('physics_rate', 1.0 / world_step_s if world_step_s
                                 else DEFAULT_PHYSICS_RATE)
        odom_rate = self.rate('odom_rate', float(drive.odometry_rate))
        real_time_factor = self.rate('real_time_factor', 1.0)
        stamped = self.declare_parameter('cmd_vel_stamped', Parameter.Type.BOOL).value
        publish_tf = self.declare_parameter('publish_tf', bool(drive.publish_tf)).value
        command_timeout = self.command_timeout(drive)
        self.sim = self.start_simulator(world, limits, command_timeout)
        #: The spawn pose (x m, y m, yaw rad in the world): odometry's origin, as Gazebo's
        #: DiffDrive starts odometry at (0, 0, 0) in odom wherever the robot was spawned.
        self.odom_origin = self.sim.pose
        self.step_ns = round(NANOSECONDS_PER_SECOND / physics_rate)
        self.step_s = self.step_ns / NANOSECONDS_PER_SECOND
        self.scan_schedule = self.schedule(
            'lidar update_rate', self.sim.lidar_config.update_rate, physics_rate)
        self.odom_schedule = self.schedule('odom_rate', odom_rate, physics_rate)
        self.steps = 0
        self.collisions_reported = 0
        #: Called as ``on_publish(topic, msg, data)`` after each message the bridge publishes
        #: itself, with the CDR bytes ``data`` it published (rclpy's ``serialize_message``).
        self.on_publish = None
        #: Stepped: called as ``on_unheard(topic, type_name, make_data)`` instead of a publish
        #: for odometry no subscription would receive; ``make_data()`` returns its CDR bytes
        #: (see :meth:`publish_odometry`). None: every message is published.
        self.on_unheard = None
        # Stepped, every QoS event handler is one more entity in every wait of the executor;
        # the other side's handlers still report incompatible QoS.
        events, cmd_vel_events = ({}, {}) if not stepped else (
            {'event_callbacks': PublisherEventCallbacks(use_default_callbacks=False)},
            {'event_callbacks': SubscriptionEventCallbacks(use_default_callbacks=False)})
        self.create_publishers(drive, publish_tf, events)
        self.start_commands(drive, stepped, stamped, cmd_vel_events)
        if not stepped:
            # For RViz (params/lab.rviz), live only: nobody watches a stepped run's displays.
            x, y, yaw = self.odom_origin
            publish_scene(self, world, self.frames, (x, y, 0.0, 0.0, 0.0, yaw),
                          self.sim.lidar_config.pose)
            # The steady clock: this timer makes sim time, so it cannot wait for it.
            self.create_timer(1.0 / physics_rate / real_time_factor, self.step,
                              clock=RclpyClock(clock_type=ClockType.STEADY_TIME))

    def declare_frames(self, world: World, drive: DiffDriveConfig) -> dict[str, str]:
        """Declare the odom, base_link and laser frame parameters; return {name: frame}."""
        lidar_frame = world.robot.lidar.frame_id if world.robot.lidar else LidarConfig.frame_id
        return {name: self.declare_parameter(name + '_frame', default).value
                for name, default in (('odom', drive.odometry_frame),
                                      ('base_link', drive.base_frame),
                                      ('laser', lidar_frame))}

    def command_timeout(self, drive: DiffDriveConfig) -> float:
        """Declare ``cmd_vel_timeout`` (s; 0: keep the last command) and return it."""
        # 0: keep the last command until the next, as Gazebo's DiffDrive does.
        command_timeout = self.declare_parameter('cmd_vel_timeout',
                                                 float(drive.command_timeout or 0.0)).value
        if not (math.isfinite(command_timeout) and command_timeout >= 0.0):
            raise ValueError("parameter 'cmd_vel_timeout' must be 0 (keep the last command) or "
                             f'a positive number of s, got {command_timeout!r}')
        return command_timeout

    def start_simulator(self, world: World, limits: DriveLimits,
                        command_timeout: float) -> Simulator:
        """Return the simulator of ``world``, with the simulator's own parameters declared."""
        return Simulator(
            world,
            seed=self.declare_parameter('seed', 0).value,
            limits=limits,
            command_timeout=command_timeout if command_timeout > 0.0 else None,
            lidar_samples=self.optional('lidar_samples', 0),
            lidar_noise_stddev=self.optional('lidar_noise_stddev', -1.0),
            gui=self.declare_parameter('gui', False).value,
            draw_rays=self.declare_parameter('draw_rays', False).value)

    def create_publishers(self, drive: DiffDriveConfig, publish_tf: bool, events: dict) -> None:
        """Create the scan, odometry, clock, collision and TF publishers and their messages."""
        self.scan_pub = self.create_publisher(LaserScan, 'scan', 10, **events)
        self.odom_pub = self.create_publisher(Odometry, relative(drive.odometry_topic), 10,
                                              **events)
        self.clock_pub = self.create_publisher(Clock, 'clock', 10, **events)
        self.collision_pub = self.create_publisher(PointStamped, 'collisions', 10, **events)
        self.tf_broadcaster = None
        if TransformBroadcaster is None:
            self.get_logger().warning(NO_TF_WARNING)
        else:
            if publish_tf:
                self.tf_broadcaster = TransformBroadcaster(self)
            StaticTransformBroadcaster(self).sendTransform(self.static_transforms())
        # Messages published every step are filled in place: publishing copies them.
        self.clock = Clock()
        self.odom = Odometry(child_frame_id=self.frames['base_link'])
        self.odom.header.frame_id = self.frames['odom']
        self.odom_transform = self.transform(self.clock.clock, self.frames['odom'],
                                             self.frames['base_link'], (0.0, 0.0, 0.0),
                                             (0.0, 0.0, 0.0))

    def start_commands(self, drive: DiffDriveConfig, stepped: bool, stamped: bool | None,
                       events: dict) -> None:
        """Set up the command topic; subscribe now when its type is known or the run is live."""
        self.command_topic = self.resolve_topic_name(relative(drive.command_topic))
        self.command_events = events
        self.command_subscription = None
        #: Called as ``listener(msg_type)`` when the bridge subscribes to its commands, and as
        #: ``listener(None)`` before it drops that subscription for one of the other type.
        self.command_listeners = []
        self.command_publisher_count = 0
        self.command_check_steps = [max(1, round(period / self.step_s))
                                    for period in COMMAND_GRAPH_CHECK_S]
        self.next_command_check = 0
        #: Whether the command type may follow the publishers (cmd_vel_stamped unset).
        self.command_type_follows = stamped is None
        if stamped is not None:
            self.subscribe_command(TwistStamped if stamped else Twist)
        elif not stepped:
            # Live, the nodes are other processes (other DDS participants): subscribe now, as
            # Gazebo's bridge does, so that discovery runs while they start; a publisher of the
            # other type shows on the graph and the subscription follows it.
            self.subscribe_command(Twist)
        else:
            self.check_command_publishers()

    def rate(self, name, default):
        """Declare a parameter that must be positive and finite: a rate in Hz, or a factor."""
        value = self.declare_parameter(name, default).value
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"parameter '{name}' must be positive and finite, got {value!r}")
        return value

    def schedule(self, name, rate, physics_rate):
        """Return the UpdateSchedule of ``rate`` (Hz); warn when the physics cannot keep it."""
        if rate > physics_rate:
            self.get_logger().warning(
                f'{name} {rate:g} Hz is above physics_rate {physics_rate:g} Hz: publishing '
                f'every physics step, at {physics_rate:g} Hz')
        return UpdateSchedule(rate)

    def load_world(self) -> World:
        """
        Return the world the parameter ``world`` names, with the robot ``robot`` at ``robot_pose``.

        ``robot`` names a model folder (as the world file's ``robot: model:``; empty: the
        world's own robot) put at ``robot_pose`` (x m, y m, yaw rad; unset: where the world puts
        its robot), as ``ros_gz_sim create`` spawns a model into a Gazebo world.
        """
        name = self.declare_parameter('world', 'obstacles').value
        robot = self.declare_parameter('robot', '').value
        pose = self.declare_parameter('robot_pose', Parameter.Type.DOUBLE_ARRAY).value
        if pose is not None and len(pose) != 3:
            raise ValueError(f"parameter 'robot_pose' must be [x, y, yaw] (m, m, rad), got "
                             f'{list(pose)}')
        if robot:
            return World.load(name, robot=robot, robot_pose=pose)
        world = World.load(name)
        return world if pose is None else world.with_robot_start(*pose)

    def optional(self, name, unset):
        """Declare a parameter whose default ``unset`` means 'as the robot model says'."""
        value = self.declare_parameter(name, unset).value
        return None if value == unset else value

    def subscribe_command(self, msg_type=None):
        """
        Subscribe to the command topic (once) and return the message type it takes.

        ``msg_type`` (Twist or TwistStamped) when none is on the graph yet; default Twist.
        """
        if self.command_subscription is None:
            self.command_subscription = self.create_subscription(
                msg_type or Twist, self.command_topic, self.on_cmd_vel, 10,
                **self.command_events)
            for listener in self.command_listeners:
                listener(self.command_subscription.msg_type)
        return self.command_subscription.msg_type

    def resubscribe_command(self, msg_type) -> None:
        """
        Take commands of ``msg_type`` instead of the type subscribed to.

        The old subscription, and the listeners' (who are told None first), go before the new
        one is made: one DDS participant holds one type per topic.
        """
        for listener in self.command_listeners:
            listener(None)
        self.destroy_subscription(self.command_subscription)
        self.command_subscription = None
        self.subscribe_command(msg_type)

    def check_command_publishers(self) -> None:
        """
        Subscribe with the type the command topic's publishers use, once one shows.

        Publishers of both types at once: one error line naming them, logged when the
        publishers change; the bridge keeps the type it has. The graph is asked only when the
        number of publishers changed.
        """
        count = self.count_publishers(self.command_topic)
        if count == self.command_publisher_count:
            return
        self.command_publisher_count = count
        publishers: dict[str, list[str]] = {}
        for info in self.get_publishers_info_by_topic(self.command_topic):
            name = '/'.join(part for part in (info.node_namespace.strip('/'), info.node_name)
                            if part)
            publishers.setdefault(info.topic_type, []).append(name)
        msg_type, error = command_type(self.command_topic, publishers)
        if error:
            self.get_logger().error(error)
        elif msg_type is not None and self.command_subscription is None:
            self.subscribe_command(msg_type)
        elif msg_type is not None and self.command_type_follows and \
                msg_type is not self.command_subscription.msg_type:
            self.resubscribe_command(msg_type)

    def on_cmd_vel(self, msg):
        twist = getattr(msg, 'twist', msg)
        warning = self.sim.set_command(twist.linear.x, twist.angular.z)
        if warning:
            self.get_logger().warning(f'cmd_vel: {warning}', throttle_duration_sec=1.0)

    @property
    def now_ns(self) -> int:
        """Return the simulated time (ns) of the last physics step."""
        return self.steps * self.step_ns

    def quiet_steps(self, until_ns: int) -> int:
        """
        Return how many physics steps the next :meth:`step` can take as one (at least 1).

        The steps up to the first at or after ``until_ns`` (the caller's next event: a node's
        timer, the run's end), the next scan or odometry, or the next look at the command
        topic: no message goes out and no command can come in before the last of them. The
        simulator drives them as it would one by one (Simulator.step's ``substeps``); a drive
        with a command timeout to keep takes one step at a time.
        """
        if self.sim.command_timeout is not None:
            return 1
        next_ns = min(until_ns, self.scan_schedule.next_ns, self.odom_schedule.next_ns,
                      self.next_command_check * self.step_ns)
        return max(1, -(-next_ns // self.step_ns) - self.steps)

    def step(self, clock_due: bool = True, steps: int = 1) -> bool:
        """
        Advance the physics ``steps`` steps in one and publish what is due after them.

        Returns True if anyone hears it. ``steps`` > 1 only as :meth:`quiet_steps` allows.
        /clock goes out with every other message, and on its own when ``clock_due`` (live: every
        step; a stepped runner asks for it only when a node's timer falls due). The return
        value tells a stepped runner whether a callback may now be ready: a message went to a
        topic with a subscriber, or /clock did.
        """
        if self.steps >= self.next_command_check:
            self.check_command_publishers()
            self.next_command_check = self.steps + self.command_check_steps[
                self.command_subscription is not None]
        self.sim.step(self.step_s, steps)
        self.steps += steps
        now_ns = self.now_ns
        stamp = self.clock.clock
        stamp.sec, stamp.nanosec = divmod(now_ns, NANOSECONDS_PER_SECOND)
        due = []
        if self.scan_schedule.due(now_ns):
            due.append((self.scan_pub, self.scan_message(stamp)))
        odom_due = self.odom_schedule.due(now_ns)
        if odom_due:
            due.append((self.odom_pub, self.odometry_state()))
        collisions = self.sim.collisions
        while self.collisions_reported < len(collisions):
            due.append((self.collision_pub,
                        self.report_collision(collisions[self.collisions_reported], stamp)))
            self.collisions_reported += 1
        send_tf = self.tf_broadcaster is not None and odom_due
        heard = (clock_due or any(publisher.get_subscription_count() for publisher, _ in due)
                 or (send_tf and self.tf_broadcaster.pub_tf.get_subscription_count() > 0))
        if heard:
            self.publish(self.clock_pub, self.clock)
        for publisher, msg in due:
            if publisher is self.odom_pub:
                self.publish_odometry(msg, send_tf)
            else:
                self.publish(publisher, msg)
        if send_tf:
            self.odom_transform.header.stamp = stamp
            self.tf_broadcaster.sendTransform(self.odom_transform)
        return heard

    def publish(self, publisher, msg) -> None:
        """
        Publish ``msg``; then hand it to ``on_publish`` (topic, msg, its bytes) if that is set.

        Serialised once: rclpy publishes the bytes as they are, and a recorder stores them.
        """
        data = serialize_message(msg)
        publisher.publish(data)
        if self.on_publish is not None:
            self.on_publish(publisher.topic_name, msg, data)

    def scan_message(self, stamp) -> LaserScan:
        """
        Return the scan taken now, stamped ``stamp``.

        ``scan_time`` is the time (s) since the previous scan (since the start for the first):
        1/update_rate on average, one physics step more or less when the rate does not divide
        the physics rate. ``time_increment`` is 0: every beam is cast at the same instant.
        """
        scan = self.sim.scan()
        msg = LaserScan(angle_min=float(scan.angle_min), angle_max=float(scan.angle_max),
                        angle_increment=float(scan.angle_increment),
                        time_increment=float(scan.time_increment),
                        scan_time=self.scan_schedule.elapsed_ns / NANOSECONDS_PER_SECOND,
                        range_min=float(scan.range_min),
                        range_max=float(scan.range_max), ranges=float32_array(scan.ranges),
                        intensities=float32_array(scan.intensities))
        msg.header.stamp = stamp
        msg.header.frame_id = self.frames['laser']
        return msg

    def odometry_state(self) -> tuple[int, int, float, float, float, float, float, float]:
        """
        Return what odometry says now: the stamp, the pose in ``odom``, the velocity.

        (stamp s, stamp ns, x m, y m, sin(yaw / 2), cos(yaw / 2), linear m/s, angular rad/s).
        """
        x, y, yaw = pose_from(self.odom_origin, self.sim.pose)
        linear, angular = self.sim.velocity
        # A rotation about z only: (0, 0, sin(yaw / 2), cos(yaw / 2)).
        return (*divmod(self.now_ns, NANOSECONDS_PER_SECOND), float(x), float(y),
                math.sin(yaw / 2.0), math.cos(yaw / 2.0), float(linear), float(angular))

    def publish_odometry(self, state: tuple, send_tf: bool) -> None:
        """
        Publish odometry ``state`` (see :meth:`odometry_state`), or hand it to ``on_unheard``.

        Stepped, odometry no subscription would receive (and no TF to send) is not published:
        ``on_unheard`` (the recorder) gets the topic, the type and what makes its bytes later.
        """
        if self.on_unheard is not None and not send_tf and \
                self.odom_pub.get_subscription_count() == 0:
            self.on_unheard(self.odom_pub.topic_name, ODOMETRY_TYPE,
                            partial(self.odometry_bytes, state))
        else:
            self.publish(self.odom_pub, self.odometry(state))

    def odometry_bytes(self, state: tuple) -> bytes:
        """Return the CDR bytes of the odometry message of ``state``."""
        return serialize_message(self.odometry(state))

    def odometry(self, state: tuple) -> Odometry:
        """Fill the odometry message (and the odom → base_link transform) with ``state``."""
        sec, nanosec, x, y, half_yaw_sin, half_yaw_cos, linear, angular = state
        odom = self.odom
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
        pose = odom.pose.pose
        pose.position.x, pose.position.y = x, y
        pose.orientation.z, pose.orientation.w = half_yaw_sin, half_yaw_cos
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = linear, angular
        translation = self.odom_transform.transform.translation
        translation.x, translation.y = pose.position.x, pose.position.y
        rotation = self.odom_transform.transform.rotation
        rotation.z, rotation.w = half_yaw_sin, half_yaw_cos
        return odom

    def static_transforms(self) -> list[TransformStamped]:
        """
        Return the robot's fixed frames, as robot_state_publisher sends them from its joints.

        Each joint between two of the model's links, from the drive's base frame down (e.g.
        base_footprint -> base_link -> base_scan), the laser frame at the lidar sensor's own
        pose; a robot without such a tree: base frame -> laser frame.
        """
        stamp = Time().to_msg()
        base, laser = self.frames['base_link'], self.frames['laser']
        lidar = self.sim.lidar_config.pose
        transforms, reached = [], {base}
        joints = list(self.sim.world.robot.joints)
        while joints:  # breadth first from the base: only its subtree, parents first
            below = [joint for joint in joints if joint[0] in reached]
            if not below:
                break
            for parent, child, parent_pose, child_pose in below:
                pose = relative_pose(parent_pose, lidar if child == laser else child_pose)
                transforms.append(self.transform(stamp, parent, child, pose[:3], pose[3:]))
                reached.add(child)
                joints.remove((parent, child, parent_pose, child_pose))
        if laser not in reached:
            transforms.append(self.transform(stamp, base, laser, lidar[:3], lidar[3:]))
        return transforms

    def transform(self, stamp, parent, child, translation, rotation_rpy) -> TransformStamped:
        """Return the transform from frame ``parent`` to ``child`` (names) at a pose (m, rad)."""
        transform = TransformStamped()
        transform.header.stamp = stamp
        transform.header.frame_id = parent
        transform.child_frame_id = child
        offset = transform.transform.translation
        offset.x, offset.y, offset.z = (float(value) for value in translation)
        rotation = transform.transform.rotation
        rotation.x, rotation.y, rotation.z, rotation.w = quaternion_from_euler(*rotation_rpy)
        return transform

    def report_collision(self, collision, stamp) -> PointStamped:
        """Log a new contact and return its /collisions message."""
        self.get_logger().warning(
            f'collision with {collision.obstacle} at t={collision.time:.2f} s, '
            f'x={collision.x:.2f} m, y={collision.y:.2f} m')
        point = PointStamped()
        point.header.stamp = stamp
        point.header.frame_id = self.frames['odom']
        x, y, _ = pose_from(self.odom_origin, (collision.x, collision.y, 0.0))
        point.point.x, point.point.y = float(x), float(y)
        return point

    def destroy_node(self):
        self.sim.close()
        return super().destroy_node()


def main(args=None):
    """
    Spin the simulator until Ctrl-C, which also ends it cleanly while the world is loading.

    A bad parameter (``-p world:=5``), an unknown world, or a world or robot file it cannot
    load ends the process with one line naming it (exit status 1), never a traceback.
    """
    rclpy.init(args=args)
    try:
        try:
            node = SimBridge()
        except START_ERRORS as error:
            sys.exit(f'sim_bridge: cannot start: {one_line(str(error))}')
        try:
            rclpy.spin(node)
        finally:
            node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()

"""tf2_ros for the lockstep runtime: the two broadcasters (publishing only, no listener)."""

from sim_bridge.lockstep.tf2_ros.static_transform_broadcaster import StaticTransformBroadcaster
from sim_bridge.lockstep.tf2_ros.transform_broadcaster import TransformBroadcaster

__lockstep__ = True
__all__ = ['StaticTransformBroadcaster', 'TransformBroadcaster']

"""
The simulator: Gazebo's stand-in, pure Python with no rclpy (its ROS face: ros.bridge).

Read it as a table of contents:

- :mod:`.world`: world files (the kit's YAML, Gazebo's SDF), validated into a
  :class:`~.world.World`;
- :mod:`.sdf`: Gazebo model folders and SDF files: collisions, the lidar, the diff-drive plugin;
  its parts :mod:`.sdf_values` (values, poses), :mod:`.sdf_frames` (frames),
  :mod:`.sdf_lookup` (model folders, URIs), :mod:`.sdf_geometry` (collisions),
  :mod:`.sdf_lidar` (:class:`~.sdf_lidar.LidarConfig`), :mod:`.sdf_drive` (the diff drive),
  and :mod:`.sdf_model` (the :class:`~.sdf_model.Model` and world it makes);
- :mod:`.meshes`: the triangle meshes models name (STL, OBJ, DAE) and extruded polylines;
- :mod:`.geometry`: poses, collision shapes, their floor outlines and triangle meshes;
- :mod:`.robot`: the differential drive (velocity and acceleration limits, arc integration);
- :mod:`.lidar`: the planar lidar as pybullet ray casts against the world's shapes;
- :mod:`.simulator`: one world and one robot stepped on simulated time, with contacts;
- :mod:`.viewer`: the optional pybullet window.

Nothing here imports the bridge, the runner or the grader.
"""

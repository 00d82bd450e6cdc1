"""previewctl on ROS 2 (the ``[ros]`` extra): a node that drives a ros2_control velocity interface.

* :mod:`~previewctl.ros.settings`: the node's settings, its ROS parameters;
* :mod:`~previewctl.ros.build`: the robot, the hand path and the controller they make;
* :mod:`~previewctl.ros.markers`: obstacle markers to observations;
* :mod:`~previewctl.ros.safety`: when the node stops the arm, and the last guard on a command;
* :mod:`~previewctl.ros.environment`: the loopback-only DDS environment (tests, trials on one machine);
* :mod:`~previewctl.ros.node`: the node; :mod:`~previewctl.ros.fake`: a fake robot and a moving sphere;
* :mod:`~previewctl.ros.run`: ``previewctl ros``.

Nothing else in the package imports this one; its modules that import ``rclpy`` (``node``, ``fake``, ``run``) need
the extra, the others do not. The guide is ``docs/guide/ros.md``.
"""

"""The ROS 2 bridge ``srcs-ros2`` (``docs/ros2.md``): a client of the supervisor's socket API
that brings the remote, the supervisor's state and its stops into a robot's ROS graph.

The daemon stays free of ROS: this package is never imported by ``srcsd``. Only
:mod:`supervisord.ros2.node` imports rclpy; the rest is pure (``mapping``, ``diagnostics``,
``gate``) or speaks only the socket API (``link``), and runs on Python 3.10 to 3.14, every
ROS 2 distribution's. It ships as a package of its own with the client library it imports
(``ros2/``, ``python3-srcs-ros2``: docs/ros2.md "Install").
"""

"""The ROS 2 bridge ``srcs-ros2`` (``docs/ros2.md``): a client of the supervisor's socket API
that brings the remote, the supervisor's state and its stops into a robot's ROS graph.

The daemon stays free of ROS: this package is never imported by ``srcsd``. Only
:mod:`supervisord.ros2.node` imports rclpy; the rest is pure (``mapping``, ``diagnostics``,
``gate``) or speaks only the socket API (``link``), and runs on Python 3.10 to 3.12.
"""

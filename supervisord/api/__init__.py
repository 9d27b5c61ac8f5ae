"""The client API (SR-8, ``docs/api.md``): the local Unix socket that serves the robot's
programs and ``srcsctl``. Sans-IO: :mod:`.framing` cuts lines and builds error replies,
:mod:`.requests` parses requests, :mod:`.views` builds replies and pushes, :mod:`.translate`
turns requests into safety-core events. :mod:`.server` is the non-blocking server the daemon's
loop drives, :mod:`.credentials` says who is at the other end. The robot's programs use
:mod:`supervisord.client`.

Nothing is imported here: the client library imports only :mod:`.framing` and
:mod:`.requests`, which must run on the ROS bridge's Python (``docs/ros2.md``)."""

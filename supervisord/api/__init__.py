"""The client API (SR-8, ``docs/api.md``): the local Unix socket that serves the robot's
programs and ``srcsctl``. Sans-IO: :mod:`.framing` cuts lines and builds error replies,
:mod:`.ops` holds the requests and :mod:`.requests` parses them; the replies and pushes are
the typed values of :mod:`.replies` and :mod:`.pushes` (their parts in :mod:`.status`,
:mod:`.records` and :mod:`.messages`, read back with :mod:`.wire`), which :mod:`.views` builds
from the daemon's values; :mod:`.translate` turns requests into safety-core events.
:mod:`.connection` is one connection's protocol, both ends, without I/O: the server and the
client library each drive it. :mod:`.server` is the non-blocking server the daemon's loop
drives, :mod:`.credentials` says who is at the other end. The robot's programs use
:mod:`supervisord.client`.

Nothing is imported here: the client library imports only :mod:`.connection` and the
vocabulary (:mod:`.framing`,
:mod:`.ops`, :mod:`.wire`, :mod:`.status`, :mod:`.records`, :mod:`.messages`,
:mod:`.replies`, :mod:`.pushes`), which must run on the ROS bridge's Python and loads nothing
of the safety core (``docs/ros2.md``)."""

"""The ground station's API, one router per area; ``seaway_groundstation.app`` includes them.

* ``fleet``: the vessels seen and their latest messages, the live metrics, the page's settings, the
  live stream (WebSocket);
* ``missions``: send, import, check, parse, export, start, pause, resume and abort missions;
* ``vehicle``: arm, disarm, home, autopilot mode, the simulated scenario;
* ``replay``: recordings under the runs folder or uploaded, cut into the live stream's frames;
* ``page``: the page itself and its map tiles (not in the schema);
* ``common``: what the routers share (the vessel name, the error answers each documents).
"""

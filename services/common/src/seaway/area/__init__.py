"""A vessel's operating area: where it may go (a keep-in polygon), where it must not (keep-out
polygons and circles), and where it may go to wait (rally points).

* ``seaway.area.geometry``: the plane geometry (points, segments, polygons, circles), pure;
* ``seaway.area.model``: the typed area in local NED metres, its validation, and the checks of a
  point, a mission's path and a predicted trajectory against it;
* ``seaway.area.files``: the area as written in files: Seaway's TOML ``[area]`` table, the
  ``geoFence`` and ``rallyPoints`` of a QGroundControl ``.plan``, and GeoJSON.
"""

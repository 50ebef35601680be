"""A vessel's operating area: where it may go (a keep-in polygon), where it must not (keep-out
polygons and circles), and where it may go to wait (rally points).

* ``seaway.area.geometry``: the plane geometry (points, segments, polygons, circles), pure;
* ``seaway.area.model``: the typed area in local NED metres, its validation, and the checks of a
  point, a mission's path and a predicted trajectory against it;
* ``seaway.area.files``: the area as written in files (the formats, and ``load_area_file``):
  ``spec`` (``AreaSpec``, as a file gives it, and Seaway's TOML ``[area]`` table), ``plan`` (the
  ``geoFence`` and ``rallyPoints`` of a QGroundControl ``.plan``) and ``geojson``.
"""

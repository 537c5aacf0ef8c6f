"""Mission and area file formats: QGroundControl .plan, QGC WPL 110 .waypoints, GeoJSON, KML.

Each format module offers pure ``loads(text) -> model`` / ``dumps(model) -> text`` functions and
thin ``read(path)`` / ``write(path, model)`` wrappers. Output is deterministic.
"""

"""Plain data that travels with the passes: the scene description and the fit values it carries,
the pass table, EXR files, thickness maps, extents."""

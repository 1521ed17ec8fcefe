"""SSS Lab core: pure NumPy (and OpenEXR) — never imports bpy, runs on any render-farm node."""

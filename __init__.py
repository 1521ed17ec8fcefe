"""SSS Lab: real-time subsurface scattering approximations, measured against Cycles.

The repository root is both the Blender extension and the Python package ``sss_lab``.
Importing it never imports bpy, so that ``sss_lab.core`` and ``python -m sss_lab apply`` run on
machines without Blender; Blender calls ``register``/``unregister``.
"""


def register():
    from .addon import register as _register

    _register()


def unregister():
    from .addon import unregister as _unregister

    _unregister()

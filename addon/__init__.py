"""Registration of SSS Lab's Blender classes.

Each module lists its classes in one ``classes`` tuple; they are registered in the order of
``_MODULES`` and unregistered in reverse. Errors are not swallowed: a class that fails to
register is a bug to see, and the classes registered before it are unregistered again.
"""

from __future__ import annotations

import importlib

#: Modules (relative to the package root) whose ``classes`` tuples are registered, in order.
_MODULES = (
    ".addon.properties",
    ".operators.scan",
    ".operators.thickness",
    ".operators.render",
    ".operators.apply",
    ".operators.presets",
    ".operators.comparison",
    ".operators.eevee_match",
    ".operators.export",
    ".operators.fit",
    ".operators.compositing",
    ".addon.panels",
    ".addon.panel_bake",
    ".addon.panel_material",
)

_registered: list = []
#: Handle of the ``blender --command sss_lab`` command, while registered.
_cli_handle = None


def _modules():
    root = __package__.rpartition(".")[0]
    return [importlib.import_module(name, root) for name in _MODULES]


def _render_handlers():
    """The render handlers of the compositor path (registered with the classes)."""
    return importlib.import_module(".addon.compositor_render", __package__.rpartition(".")[0])


def register():
    import bpy

    from ..blender import compat
    from . import cli, properties

    if not compat.is_supported():
        raise RuntimeError(
            f"SSS Lab needs Blender {'.'.join(map(str, compat.MIN_VERSION))} or newer, this is {bpy.app.version_string}"
        )
    _numba_cache_in_user_directory()
    try:
        for module in _modules():
            for cls in module.classes:
                bpy.utils.register_class(cls)
                _registered.append(cls)
        properties.attach()
        _render_handlers().register_handlers()
        global _cli_handle
        _cli_handle = bpy.utils.register_cli_command(cli.BLENDER_COMMAND, cli.blender_command)
    except Exception:
        unregister()
        raise


def _numba_cache_in_user_directory():
    """The compiled kernels' cache goes to the extension's user directory (an installed
    extension's own folder may not be writable); a package that is not an installed extension
    (tests, the bpy module) keeps ``core.compute.backend``'s user cache folder."""
    import bpy

    from ..core.compute import backend

    root = __package__.rpartition(".")[0]
    if root.startswith("bl_ext."):
        path = bpy.utils.extension_path_user(root, path="numba", create=True)
        backend.set_cache_dir(path)
        _prepare_in_background(root, path)


def _prepare_in_background(root: str, path: str) -> None:
    """Compile this version's kernels in a background process (``blender/prepare.py``); a failure
    to start it costs only the wait at the first Apply, so it is said and registration goes on."""
    from ..blender import prepare

    try:
        prepare.start(root, path)
    except Exception as exc:  # an OS refusal, a damaged cache folder: never a failed registration
        print(f"SSS Lab: could not start compiling the kernels in the background ({exc})")


def unregister():
    import bpy

    from . import properties

    global _cli_handle
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
    _render_handlers().unregister_handlers()
    properties.detach()
    while _registered:
        bpy.utils.unregister_class(_registered.pop())

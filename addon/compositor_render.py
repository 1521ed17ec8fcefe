"""Renders through SSS Lab's compositor node groups see the subsurface materials as plain diffuse.

The node groups scatter the Diffuse passes themselves, so Cycles must not scatter them first:
a material rendered with Subsurface Weight > 0 would be scattered twice. Instead of asking the
artist to zero the weights by hand (and to put them back for every other use of the file),
render handlers do around every render of such a scene what Render Passes does around its
own: when the render job starts (``render_init``) every Principled BSDF of the rendered
materials gets Subsurface Weight 0, its links cut (``blender.render_passes.zero_subsurface``), and
when it ends (``render_complete`` or ``render_cancel``) everything is put back
(``SceneState``). The file keeps its weights: the viewport, EEVEE, Compare and a new set-up
still see them. The handlers are registered with the add-on and stay across file loads.

They act only when the scene's compositor holds a node SSS Lab added (not muted), the render
uses compositing (Output Properties > Post Processing > Compositing) and the engine is Cycles
(``nodes.setup.uses_node_groups``). Render Passes renders with compositing off and Compare
renders its references with compositing off, so neither is touched. The set-up switches on Lock
Interface (``render.use_lock_interface``): Blender's documentation asks for it when handlers
change data during a render, so that the viewport does not read the materials while they change.
"""

from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from ..blender.state import SceneState
from ..nodes.setup import uses_node_groups

#: Scenes whose materials are changed for the render that is running (key: the scene's pointer).
_active: dict[int, SceneState] = {}


def begin(scene) -> list[str]:
    """Render ``scene``'s subsurface materials as plain diffuse until ``end(scene)``; returns the
    names of the materials whose Principled BSDF changed (empty when nothing applies)."""
    from ..blender.render_passes import zero_subsurface

    if not uses_node_groups(scene) or scene.as_pointer() in _active:
        return []
    state = SceneState()
    try:
        changed = zero_subsurface(state, scene)
    except Exception:
        state.restore()
        raise
    _active[scene.as_pointer()] = state
    return changed


def end(scene) -> bool:
    """Put back what ``begin(scene)`` changed; False when it changed nothing."""
    state = _active.pop(scene.as_pointer(), None) if scene is not None else None
    if state is None:
        return False
    state.restore()
    return True


#: Notes already printed per scene (a note repeats on every frame of an animation otherwise).
_said: dict[int, set[str]] = {}


def follow_frame(scene) -> list[str]:
    """Bring the compositor's SSS Lab groups to ``scene`` at its current frame (lights and camera as
    animated, ``nodes.setup.follow_scene``); returns its notes. Nothing to do without such groups."""
    from ..blender import compat
    from ..blender.compositor import screen_scales
    from ..blender.describe import describe_scene, sss_materials
    from ..blender.stored import KEPT_WEIGHT
    from ..nodes.setup import follow_scene

    if not uses_node_groups(scene):
        return []
    tree = compat.compositor_tree(scene)
    if tree is None:
        return []
    materials = sss_materials(scene, kept_weight=lambda mat: mat.get(KEPT_WEIGHT))
    desc = describe_scene(scene, materials)
    return follow_scene(tree, desc, screen_scales(scene, desc))


def _follow(scene) -> None:
    """The groups follow the scene's animated lights and camera (``follow_frame``), each note said once."""
    try:
        notes = follow_frame(scene)
    except ValueError as exc:  # a scene the description cannot be made of at this frame
        notes = [str(exc)]
    said = _said.setdefault(scene.as_pointer(), set())
    for note in notes:
        if note not in said:
            said.add(note)
            print(f"SSS Lab: {note}")


@persistent
def _on_frame_change(scene, *_args):
    _follow(scene)


@persistent
def _on_render_init(scene, *_args):
    _follow(scene)  # a light moved since the set-up, on this very frame
    try:
        changed = begin(scene)
    except ValueError as exc:  # e.g. a linked material: render as it is, and say why
        print(f"SSS Lab: {exc}; the compositor's node groups scatter light Cycles already scattered")
        return
    if changed:
        print(
            f"SSS Lab: {len(changed)} material(s) render as plain diffuse for the compositor's node groups "
            f"({', '.join(changed)}); their Subsurface Weight is put back after the render"
        )


@persistent
def _on_render_end(scene, *_args):
    end(scene)


_HANDLERS = (
    ("render_init", _on_render_init),
    ("render_complete", _on_render_end),
    ("render_cancel", _on_render_end),
    ("frame_change_post", _on_frame_change),
)


def register_handlers() -> None:
    for name, function in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if function not in handlers:
            handlers.append(function)


def unregister_handlers() -> None:
    for name, function in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while function in handlers:
            handlers.remove(function)
    for key in list(_active):  # a render still running when the add-on goes: put the materials back
        _active.pop(key).restore()

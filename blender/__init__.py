"""Blender services that are not operators: the scene description from a scene, scene state
save and restore, the thickness bake, render passes, the compositor set-up, the comparison with
Cycles and its reference cache, and the seam between Blender versions (``compat``).

They import ``core`` and bpy, never ``operators`` or ``addon``; operators and the command line
call them with plain arguments.
"""

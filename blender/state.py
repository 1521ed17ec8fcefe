"""Change a Blender scene temporarily and put it back exactly, also on failure.

Every job that renders or bakes changes settings (samples, passes, material inputs, node
links) and must leave the scene as it found it. ``SceneState`` records each change before it
makes it and undoes them in reverse order on ``restore`` — which the ``with`` statement calls
whether the block succeeded, failed or was cancelled.
"""

from __future__ import annotations


def _copy(value):
    """Detach bpy arrays (colours, vectors) from the data they view."""
    try:
        return tuple(value) if not isinstance(value, (str, bytes)) and hasattr(value, "__len__") else value
    except TypeError:
        return value


class SceneState:
    def __init__(self):
        self._undo: list = []

    def set(self, owner, attr: str, value) -> None:
        """``setattr(owner, attr, value)``, remembering the old value."""
        old = _copy(getattr(owner, attr))
        self._undo.append(lambda: setattr(owner, attr, old))
        setattr(owner, attr, value)

    def set_input(self, node, name: str, value) -> None:
        """Set the default value of a node's input socket ``name``."""
        self.set(node.inputs[name], "default_value", value)

    def on_restore(self, undo) -> None:
        """Run ``undo()`` on restore (for additions: new nodes, links, data-blocks)."""
        self._undo.append(undo)

    def restore(self) -> None:
        """Undo every change, newest first; every undo runs even if one fails (then it re-raises)."""
        first_error = None
        while self._undo:
            undo = self._undo.pop()
            try:
                undo()
            except Exception as exc:  # keep restoring the rest, report the first failure after
                first_error = first_error or exc
        if first_error is not None:
            raise first_error

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.restore()
        return False

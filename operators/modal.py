"""Long jobs as modal operators: one step per timer event, Blender's progress API, status text, Esc.

The job is a generator (``blender/jobs.py``). In the interface the operator (``ModalJob``) runs
one step per timer event: Blender keeps drawing between steps, the status bar and the cursor show
the progress, and Esc closes the generator between two steps, which restores the scene and keeps
what was finished. A step itself (one render) cannot be interrupted. Headless (``blender -b``,
the bpy module) and from scripts (``execute``) the operator runs the job to its end.

The convention is Blender's own for long jobs (``event_timer_add``, ``modal_handler_add``,
``progress_begin/update/end``, ``status_text_set``, Esc), as in its extension manager.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import bpy

from ..blender.jobs import Job, Progress, run
from ..core.base.errors import SSSLabError


class ModalJob:
    """The modal part of an operator whose work is a job generator (mix in before
    ``bpy.types.Operator``). The operator defines:

    - ``new_job(context)``: the generator (it may raise one of ``job_errors`` at once, or at its
      first step, before changing anything);
    - ``job_done(context, result)``: report the result, return the operator's return set;
    - ``job_label``: the status-bar text's first words ("Rendering passes").

    ``execute`` runs the job to its end (scripts, headless); ``invoke`` runs it modal when there
    is a window to draw in. Interactive input other than Esc is held back while the job runs:
    the job has changed the scene temporarily, and edits made now would be undone by the restore.
    """

    #: Provided by ``bpy.types.Operator``, which this class is mixed into.
    report: Callable[..., Any]

    job_label = "Working"
    #: Errors reported in one line (the job stopped and restored the scene); anything else is a bug.
    job_errors: tuple = (SSSLabError, ValueError, RuntimeError, OSError, KeyError)
    #: Seconds between timer events: short, so that steps follow each other without delay.
    timer_step_s = 0.01

    _job = None
    _timer = None
    _progress: Progress | None = None
    _total = 0

    # -- what the operator provides -------------------------------------------------------------
    def new_job(self, context) -> Job:
        raise NotImplementedError

    def job_done(self, context, result) -> set:
        raise NotImplementedError

    def job_failed(self, exc: BaseException) -> set:
        """Report a job error (one of ``job_errors``): the job stopped and restored the scene."""
        self.report({"ERROR"}, _message(exc))
        return {"CANCELLED"}

    # -- blocking ------------------------------------------------------------------------------
    def execute(self, context):
        wm = context.window_manager
        try:
            job = self.new_job(context)
            first = next(job)
        except StopIteration as stop:  # nothing to do: the job finished in its checks
            return self.job_done(context, stop.value)
        except self.job_errors as exc:
            return self.job_failed(exc)
        wm.progress_begin(0, max(first.total, 1))
        try:
            result = run(job, lambda p: wm.progress_update(p.done))
        except self.job_errors as exc:
            return self.job_failed(exc)
        finally:
            wm.progress_end()
        return self.job_done(context, result)

    # -- modal ---------------------------------------------------------------------------------
    def interactive(self, context) -> bool:
        """True when a modal run can show progress: Blender has a window (not ``-b``)."""
        return not bpy.app.background and context.window is not None

    def invoke(self, context, event):
        if not self.interactive(context):
            return self.execute(context)
        return self.start(context)

    def start(self, context):
        """Check and plan (the job's first step), then hand the rest to timer events."""
        try:
            self._job = self.new_job(context)
            self._progress = next(self._job)
        except StopIteration as stop:
            self._job = None
            return self.job_done(context, stop.value)
        except self.job_errors as exc:
            self._job = None
            return self.job_failed(exc)
        wm = context.window_manager
        self._total = self._progress.total
        wm.progress_begin(0, max(self._total, 1))
        self._timer = wm.event_timer_add(self.timer_step_s, window=context.window)
        self.listen(context)
        self._status(context)
        return {"RUNNING_MODAL"}

    def listen(self, context) -> None:
        """Receive the window's events (``modal``) until the job ends."""
        context.window_manager.modal_handler_add(self)

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            return self._end(context, cancelled=True)
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}  # held back (see the class docstring)
        try:
            self._progress = next(self._job)
        except StopIteration as stop:
            return self._end(context, result=stop.value)
        except self.job_errors as exc:
            self._end(context, failed=True)
            return self.job_failed(exc)
        except BaseException:
            self._end(context, failed=True)
            raise
        wm = context.window_manager
        if self._progress.total != self._total:  # a job that found more to do (Fit to Cycles' extra render)
            self._total = self._progress.total
            wm.progress_begin(0, max(self._total, 1))
        wm.progress_update(self._progress.done)
        self._status(context)
        return {"RUNNING_MODAL"}

    def cancel(self, context):
        """Blender ends the operator (a file is loaded, the window closes): stop and restore."""
        if self._job is not None:
            self._end(context, cancelled=True)

    def _status(self, context) -> None:
        if context.workspace is None or self._progress is None:
            return
        p = self._progress
        context.workspace.status_text_set(
            f"{self.job_label} {p.done + 1}/{p.total}: {p.message} (Esc: cancel after this step)"
        )

    def _end(self, context, *, result=None, cancelled: bool = False, failed: bool = False):
        wm = context.window_manager
        job, self._job = self._job, None
        try:
            if job is not None:
                job.close()  # at a yield: GeneratorExit restores the scene; finished: nothing to do
        finally:
            if self._timer is not None:
                wm.event_timer_remove(self._timer)
                self._timer = None
            wm.progress_end()
            if context.workspace is not None:
                context.workspace.status_text_set(None)
        if failed:
            return {"CANCELLED"}
        if cancelled:
            return self.job_cancelled(context)
        return self.job_done(context, result)

    def job_cancelled(self, context) -> set:
        """Report a cancelled job (Esc, or Blender ended the operator); the scene is restored."""
        p = self._progress
        done = f" after {p.done} of {p.total} steps" if p is not None else ""
        kept = f"; kept: {', '.join(p.outputs)}" if p is not None and p.outputs else ""
        self.report({"WARNING"}, f"{self.job_label} cancelled{done}; the scene is as it was{kept}")
        return {"CANCELLED"}


class DialogModalJob(ModalJob):
    """A ``ModalJob`` whose settings are asked for in a dialog first (Blender's
    ``invoke_props_dialog``). The dialog's OK button calls ``execute()``, which starts the modal
    run as a new invocation of the same operator with ``confirmed=True``; from scripts and
    headless, ``execute`` runs the job to its end at once.

    The operator declares the two hidden flags itself (Blender registers only the operator's own
    property annotations)::

        confirmed: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})
        from_dialog: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})

    and ``dialog_settings()``: the properties the dialog set, passed on to the modal run.
    """

    confirmed: bool
    from_dialog: bool
    bl_idname: str

    def dialog_settings(self) -> dict:
        raise NotImplementedError

    def invoke(self, context, event):
        if self.confirmed or not self.interactive(context):
            return ModalJob.invoke(self, context, event)
        self.from_dialog = True
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        if self.from_dialog and self.interactive(context):
            module, name = self.bl_idname.split(".")
            operator = getattr(getattr(bpy.ops, module), name)
            started = operator("INVOKE_DEFAULT", confirmed=True, **self.dialog_settings())
            # This call only started the modal run (which reports when it ends).
            return {"FINISHED"} if "RUNNING_MODAL" in started else started
        return ModalJob.execute(self, context)


def _message(exc: BaseException) -> str:
    """A KeyError's message without the quotes str() adds."""
    return str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)

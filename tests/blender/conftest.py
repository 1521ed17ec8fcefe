"""Blender tests: an isolated Blender user profile, factory settings around each test.

Blender reads its user folders from the environment when bpy is first imported, so they are
pointed at a temporary folder here, before any test module imports bpy.
"""

import os
import shutil
import sys
import tempfile
import types

import pytest

if "bpy" in sys.modules:
    raise RuntimeError("bpy was imported before tests/blender/conftest.py could isolate Blender's user folders")

_USER_ROOT = tempfile.mkdtemp(prefix="sss_lab_blender_user_")
for _var, _sub in (
    ("BLENDER_USER_RESOURCES", "resources"),
    ("BLENDER_USER_CONFIG", "config"),
    ("BLENDER_USER_SCRIPTS", "scripts"),
    ("BLENDER_USER_DATAFILES", "datafiles"),
    ("BLENDER_USER_EXTENSIONS", "extensions"),
):
    os.environ[_var] = os.path.join(_USER_ROOT, _sub)
    os.makedirs(os.environ[_var], exist_ok=True)

bpy = pytest.importorskip("bpy", reason="tests/blender need the bpy module (make test installs it)")


def pytest_collection_modifyitems(config, items):
    """Tests marked ``compositor_groups`` need SSS Lab's compositor node groups: on a Blender
    that cannot run them (4.5: no Convolve node, no Menu sockets in groups) they are skipped
    with the reason (tests/blender/test_compat.py checks that the set-up says it instead)."""
    from sss_lab.blender import compat

    missing = compat.compositor_groups_missing()
    if missing is None:
        return
    skip = pytest.mark.skip(reason=missing)
    for item in items:
        if item.get_closest_marker("compositor_groups") is not None:
            item.add_marker(skip)


def _factory_reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture(autouse=True)
def factory_settings():
    """Each test starts from, and leaves, Blender's factory settings with an empty scene."""
    _factory_reset()
    yield
    _factory_reset()


@pytest.fixture
def addon():
    """SSS Lab registered from the source tree (the installed-zip path has its own test)."""
    import sss_lab

    sss_lab.register()
    try:
        yield sss_lab
    finally:
        sss_lab.unregister()


def pytest_sessionfinish(session, exitstatus):
    shutil.rmtree(_USER_ROOT, ignore_errors=True)


@pytest.fixture
def sss_quads():
    """A tiny Cycles scene for operator and render tests: a camera 4 units in front of two quads,
    "Skin" (Subsurface Weight 1) and "Wax" (its weight driven by a link from a Value node named
    "Weight"), a sun shining onto their front; 16 x 16 pixels, 4 samples, seed 0, no denoising or
    adaptive sampling. Returns the scene."""
    import math

    from sss_lab.blender import compat

    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.cycles.seed = 0
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    for name, x in (("Skin", -0.6), ("Wax", 0.6)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)], [], [(0, 1, 2, 3)])
        obj = bpy.data.objects.new(name, mesh)
        obj.location = (x, 0.0, 0.0)
        scene.collection.objects.link(obj)
        mat = bpy.data.materials.new(name)
        compat.ensure_node_tree(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Subsurface Weight"].default_value = 1.0
        bsdf.inputs["Subsurface Radius"].default_value = (0.3, 0.1, 0.05)
        mesh.materials.append(mat)
    wax = bpy.data.materials["Wax"].node_tree
    value = wax.nodes.new("ShaderNodeValue")
    value.name = "Weight"
    value.outputs[0].default_value = 1.0
    wax.links.new(value.outputs[0], wax.nodes["Principled BSDF"].inputs["Subsurface Weight"])
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.pi / 2, 0.0, 0.0)  # shines along +Y, onto the quads' front
    scene.collection.objects.link(sun)
    return scene


@pytest.fixture
def quad_weights(sss_quads):
    """``quad_weights()``: per material of ``sss_quads``, (Subsurface Weight as set, linked?)."""

    def weights():
        out = {}
        for name in ("Skin", "Wax"):
            socket = bpy.data.materials[name].node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"]
            out[name] = (socket.default_value, socket.is_linked)
        return out

    return weights


class PanelLayout:
    """A stand-in for Blender's UILayout that records what a panel draws, as rows
    (panel, kind, name, split): ``prop`` rows with whether property split was on, ``operator`` and
    ``menu`` rows (the operator id), ``label`` rows (the text). It checks that every property and
    operator named exists. Sub-layouts (column, row, box...) inherit property split, as Blender's do.
    """

    def __init__(self, rows, panel, split=False):
        self._rows, self._panel = rows, panel
        self.use_property_split, self.use_property_decorate, self.scale_y = split, False, 1.0

    def _add(self, kind, name):
        self._rows.append((self._panel, kind, name, self.use_property_split))

    def prop(self, data, name, **_):
        assert name.startswith('["') or name in data.bl_rna.properties, name
        self._add("prop", name)

    def _operator(self, idname):
        module, name = idname.split(".")
        return getattr(getattr(bpy.ops, module), name)

    def operator(self, idname, **_):
        self._operator(idname).poll()  # exists
        self._add("operator", idname)
        return types.SimpleNamespace()

    def operator_menu_enum(self, idname, prop, **_):
        assert prop in self._operator(idname).get_rna_type().properties
        self._add("menu", idname)

    def label(self, text="", **_):
        self._add("label", text)

    def separator(self, **_):
        pass

    def column(self, **_):
        return PanelLayout(self._rows, self._panel, self.use_property_split)

    row = box = split = column


def panels_of(tab):
    """SSS Lab's panels of the Properties editor tab ``tab`` in the order Blender shows them:
    each parent (registration order) followed by its sub-panels sorted by ``bl_order``."""
    import sss_lab

    panels = [
        cls
        for module in sss_lab.addon._modules()
        for cls in module.classes
        if issubclass(cls, bpy.types.Panel) and cls.bl_context == tab
    ]
    ordered = []
    for parent in [p for p in panels if not getattr(p, "bl_parent_id", "")]:
        ordered.append(parent)
        children = [p for p in panels if getattr(p, "bl_parent_id", "") == parent.bl_idname]
        ordered += sorted(children, key=lambda p: getattr(p, "bl_order", 0))
    return ordered


@pytest.fixture
def draw_panels(addon):
    """``draw_panels(tab, context=bpy.context)``: the rows (see ``PanelLayout``) of every SSS Lab
    panel of ``tab`` whose poll passes, drawn in display order."""

    def draw(tab, context=None):
        context = context or bpy.context
        rows = []
        for panel in panels_of(tab):
            if hasattr(panel, "poll") and not panel.poll(context):
                continue
            panel.draw(types.SimpleNamespace(layout=PanelLayout(rows, panel.bl_label)), context)
        return rows

    return draw


# -- driving modal operators -------------------------------------------------------------------


class ModalWindow:
    """Window manager and workspace stand-in for a modal operator: records progress, timers and
    status text (and passes nothing on to Blender)."""

    def __init__(self):
        self.progress, self.status, self.timers = [], [], []
        # The stand-in's methods are the real ones' names (the operator calls them on Blender's).
        for name in ("progress_begin", "progress_update", "progress_end", "event_timer_add", "event_timer_remove"):
            assert name in bpy.types.WindowManager.bl_rna.functions, name
        assert hasattr(bpy.types.WorkSpace, "status_text_set")

    def progress_begin(self, low, high):
        self.progress.append(("begin", low, high))

    def progress_update(self, value):
        self.progress.append(("update", value))

    def progress_end(self):
        self.progress.append(("end",))

    def event_timer_add(self, step, window=None):
        timer = types.SimpleNamespace(step=step)
        self.timers.append(timer)
        return timer

    def event_timer_remove(self, timer):
        self.timers.remove(timer)

    def status_text_set(self, text):
        self.status.append(text)


def modal_driver(operator_cls, **props):
    """``operator_cls``'s own methods (its ``ModalJob`` invoke/modal/cancel and its job) on a plain
    object: an operator instance cannot be made outside Blender's operator call. Its properties
    start at their registered defaults, then ``props``; ``reports`` collects what it reports. Only
    the hand-off to Blender's event loop (``listen``) is left out: the test sends the events."""
    import inspect

    from sss_lab.operators.modal import ModalJob

    def report(self, level, message):
        self.reports.append((next(iter(level)), message))

    keep = ("job_label", "bl_idname")
    namespace = {k: v for k, v in vars(operator_cls).items() if inspect.isfunction(v) or k in keep}
    namespace.update(report=report, listen=lambda self, context: None, interactive=lambda self, context: True)
    # The operator's ModalJob class (``ModalJob`` itself or a subclass such as ``DialogModalJob``).
    job_cls = next(c for c in operator_cls.__mro__[1:] if issubclass(c, ModalJob))
    driver = type("Driver", (job_cls,), namespace)()
    module, _, name = operator_cls.bl_idname.partition(".")
    for prop in getattr(getattr(bpy.ops, module), name).get_rna_type().properties:
        if prop.identifier != "rna_type":
            value = prop.default_flag if getattr(prop, "is_enum_flag", False) else getattr(prop, "default", None)
            setattr(driver, prop.identifier, value)
    for key, value in props.items():
        setattr(driver, key, value)
    driver.reports = []
    return driver


class ModalContext:
    """``bpy.context`` with ``window``, ``window_manager`` and ``workspace`` replaced by ``window``."""

    def __init__(self, window):
        self.window = self.window_manager = self.workspace = window

    def __getattr__(self, name):
        return getattr(bpy.context, name)


class ModalEvent:
    """A window event of ``kind`` ("TIMER", "ESC" pressed, "MOUSEMOVE"...) with only what Blender's
    ``bpy.types.Event`` has: reading anything else fails, as it would in Blender."""

    def __init__(self, kind):
        self.type, self.value = kind, "PRESS" if kind == "ESC" else "NOTHING"

    def __getattr__(self, name):
        if name in bpy.types.Event.bl_rna.properties:
            return None
        raise AttributeError(f"bpy.types.Event has no attribute {name!r}")


@pytest.fixture
def modal(addon):
    """What the modal-operator tests drive with: ``Window()``, ``driver(operator_cls, **props)``,
    ``context(window)``, ``event(kind)`` (see above)."""
    return types.SimpleNamespace(Window=ModalWindow, driver=modal_driver, context=ModalContext, event=ModalEvent)


@pytest.fixture
def built_elsewhere_in_memory():
    """``repeat(build, times)``: ``build()``'s results, each call made while one more bmesh (each a
    different size) is alive, so that what each call allocates sits at other memory addresses.
    bmesh's UV sphere numbers its edges and faces after those addresses: a result that follows
    them differs between the calls."""
    import bmesh

    alive = []

    def repeat(build, times=4):
        results = []
        for i in range(times):
            bm = bmesh.new()
            bmesh.ops.create_uvsphere(bm, u_segments=8 + 8 * i, v_segments=16, radius=1.0)
            alive.append(bm)
            results.append(build())
        return results

    yield repeat
    for bm in alive:
        bm.free()

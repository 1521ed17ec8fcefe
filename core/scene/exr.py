"""Reading and writing Blender's multilayer OpenEXR files (OpenEXR 3.5 Python API).

Layouts read (docs/references.md §7, and a probe render with bpy 5.2.3):

- Blender 5.2 writes one part per pass. The part is named ``<view layer>.<pass>`` (for example
  ``ViewLayer.Diffuse Direct``) and its channels are ``<view layer>.<pass>.<channel>``: colour
  passes ``R G B`` (``A`` for Combined and colour AOVs), Depth and Mist ``Z``, Normal and
  Position ``X Y Z``, Vector ``X Y Z W``, UV ``U V A``, Object/Material Index and value AOVs
  ``X``. Data passes (depth, normal, position, indices, value AOVs) are float32 even when the
  file is saved as half; colour passes follow the chosen colour depth.
- Blender 4.5 writes a single part holding every channel, with the short pass names of
  Blender 4.x (``ViewLayer.DiffDir.R``, ``ViewLayer.IndexMA.X``); see ``SHORT_PASS_NAMES``.

Channel names split as Blender splits them: the text after the last dot is the channel, the
text between the last two dots the pass, the rest the view layer (which may hold dots, so the
layers this project adds, ``SSSLab.burley.Image``, read back as view layer ``SSSLab.burley``).

Every array handed out is float32 (half and uint channels are converted on read, so that no
arithmetic ever happens in half precision, docs/references.md §5), rows run top to bottom
(image row 0 is the top of the picture; Blender's ``Image.pixels`` run bottom to top), and
pixels are never clamped. Files are written in float32 only, atomically, and never over an
input.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import DamagedFileError, InputError, SSSLabError
from ..base.files import atomic_write
from . import passes as _passes

#: Blender 4.x short pass names -> the names Blender 5.x writes; channel letters Blender 5.2 writes
#: per pass; where each pass is switched on. Views of the one pass table, ``core/scene/passes.py``.
SHORT_PASS_NAMES: dict[str, str] = _passes.SHORT_NAMES
PASS_CHANNELS: dict[str, str] = {p.name: p.channels for p in _passes.PASSES.values()}
pass_hint = _passes.pass_hint

#: Prefix of the layers SSS Lab adds to an output file; never chosen as the input view layer.
OUTPUT_PREFIX = "SSSLab"

# Header attributes that describe the file's structure: OpenEXR writes them itself.
_STRUCTURAL = frozenset(
    {
        "channels",
        "chunkCount",
        "compression",
        "dataWindow",
        "displayWindow",
        "lineOrder",
        "name",
        "pixelAspectRatio",
        "screenWindowCenter",
        "screenWindowWidth",
        "tiles",
        "type",
        "version",
        "maxSamplesPerPixel",
        # Per part in Blender 5.2 files (colour passes lin_rec709_scene, data passes "data"): not
        # something to copy from the first part onto whichever layer comes first in the output.
        "colorInteropID",
    }
)

# Channel orders Blender uses; a set of letters that is a subset of one is sorted by it.
_ORDERS = ("RGBA", "XYZW", "UVA")


def _import_openexr():
    try:
        import OpenEXR
    except ImportError:
        raise ImportError(
            "reading and writing EXR files needs the OpenEXR module: pip install 'OpenEXR>=3.5,<3.6'"
        ) from None
    return OpenEXR


def split_channel(full: str) -> tuple[str, str]:
    """``'ViewLayer.Diffuse Direct.R'`` -> ``('ViewLayer.Diffuse Direct', 'R')``; no dot -> ``('', full)``."""
    layer, dot, channel = full.rpartition(".")
    return (layer, channel) if dot else ("", full)


def split_layer(layer: str) -> tuple[str, str]:
    """``'ViewLayer.Diffuse Direct'`` -> ``('ViewLayer', 'Diffuse Direct')``; no dot -> ``('', layer)``."""
    view_layer, dot, pass_name = layer.rpartition(".")
    return (view_layer, pass_name) if dot else ("", layer)


def _order_channels(letters: Iterable[str]) -> tuple[str, ...]:
    letters = list(letters)
    for order in _ORDERS:
        if set(letters) <= set(order):
            return tuple(sorted(letters, key=order.index))
    return tuple(sorted(letters))


def default_channels(layer: str, n: int) -> str:
    """Channel letters for a layer of ``n`` channels, as Blender 5.2 names them.

    Known data passes (by the pass part of ``layer``) get their own letters (``Depth`` -> Z,
    ``Normal`` -> XYZ, ...); other layers get R G B (A) for 3 or 4 channels and X (Y Z W) else.
    """
    pass_name = SHORT_PASS_NAMES.get(split_layer(layer)[1], split_layer(layer)[1])
    known = PASS_CHANNELS.get(pass_name)
    if known is not None and len(known) == n:
        return known
    if n in (3, 4):
        return "RGBA"[:n]
    if 1 <= n <= 4:
        return "XYZW"[:n]
    raise ValueError(f"layer {layer!r}: {n} channels; expected 1 to 4 (give the channel letters explicitly)")


def _user_header(header: Mapping) -> dict:
    """The descriptive attributes of an OpenEXR header (strings and numbers), structure removed."""
    out = {}
    for key, value in header.items():
        if key in _STRUCTURAL:
            continue
        if isinstance(value, (str, int, float)) and not isinstance(value, bool):
            out[key] = value
    return out


#: (x min, y min, x max, y max), inclusive, as OpenEXR's box2i: a data or display window.
Window = tuple[int, int, int, int]

#: What to do about a file that cannot be read completely.
_REDO = "render the passes again (or copy the file again from where it was rendered)"

# OpenEXR's C++ library prints its warnings ("Exception raised reading pixel data for part N")
# on file descriptors 1 and 2; they are collected around a read (and folded into the error
# message) so that a damaged file gives one line, not ten, and stdout keeps only SSS Lab's lines.
_OUTPUT_LOCK = threading.Lock()


@contextlib.contextmanager
def _collect_stderr():
    lines: list[str] = []
    with _OUTPUT_LOCK, tempfile.TemporaryFile() as tmp:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (AttributeError, ValueError, OSError):
                pass
        saved = [os.dup(1), os.dup(2)]
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            lines.extend(line.strip() for line in tmp.read().decode("utf-8", "replace").splitlines() if line.strip())


def _window(value) -> Window | None:
    try:
        lo, hi = value
        return (int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1]))
    except (TypeError, ValueError, IndexError):
        return None


def _window_size(window: Window) -> tuple[int, int]:
    """(height, width) of a window."""
    return window[3] - window[1] + 1, window[2] - window[0] + 1


def _type_name(pixels: np.ndarray) -> str:
    """OpenEXR's name of the pixel type a channel was stored as, from the array it reads into."""
    names = {np.float16: "HALF", np.float32: "FLOAT", np.uint32: "UINT"}
    return names.get(pixels.dtype.type, str(pixels.dtype).upper())


@dataclass
class ExrContents:
    """Every layer of an EXR file, as read by ``read_layers``.

    ``layers`` maps the full layer name (``'ViewLayer.Diffuse Direct'``) to float32 pixels,
    (H, W) for one channel or (H, W, C); ``channels`` maps it to its channel letters in
    array order; ``half`` holds the layers that were stored as half floats; ``header`` the
    descriptive attributes of the first part (Blender puts its metadata there). ``types`` maps
    each layer to the pixel types its channels were stored as (``HALF``, ``FLOAT``, ``UINT``);
    ``data_window`` and ``display_window`` are the file's windows (``write_layers`` keeps them).
    """

    path: str
    layers: dict[str, np.ndarray]
    channels: dict[str, tuple[str, ...]]
    header: dict
    parts: int
    half: set[str] = field(default_factory=set)
    types: dict[str, frozenset] = field(default_factory=dict)
    data_window: Window | None = None
    display_window: Window | None = None

    @property
    def shape(self) -> tuple[int, int]:
        first = next(iter(self.layers.values()))
        return first.shape[:2]

    @property
    def view_layers(self) -> list[str]:
        """View layer names in file order (including SSS Lab output layers)."""
        seen: dict[str, None] = {}
        for layer in self.layers:
            seen.setdefault(split_layer(layer)[0], None)
        return list(seen)

    @property
    def windows(self) -> tuple[Window, Window] | None:
        """(data window, display window), for ``write_layers(windows=...)``; None when unknown."""
        if self.data_window is None or self.display_window is None:
            return None
        return self.data_window, self.display_window


#: The first four bytes of every OpenEXR file.
EXR_MAGIC = bytes((0x76, 0x2F, 0x31, 0x01))


def _first_reason(lines: list[str], fallback: str) -> str:
    for line in lines:
        text = line.removeprefix("Warning:").strip()
        if text:
            return text[:200]
    return fallback


def _declared_parts(OpenEXR, path: str):
    """[(part name, {channel names}, data window)] as the file's header declares them."""
    with open(path, "rb") as fh:
        magic = fh.read(4)
    if magic != EXR_MAGIC:
        what = "it is empty" if not magic else "it does not start with the OpenEXR signature"
        if magic[:1] in (b"{", b"["):
            what += " (it looks like JSON text)"
        raise DamagedFileError(
            f"{path}: not a readable OpenEXR file ({what}); pass the multilayer EXR that Blender rendered"
        )
    with _collect_stderr():
        try:
            exr = OpenEXR.File(path, header_only=True)
            declared = []
            deep = []
            for index in range(len(exr.parts)):
                header = exr.header(index)
                if header.get("type") in (OpenEXR.deepscanline, OpenEXR.deeptile):
                    deep.append((index, str(header.get("name", f"part {index}")), header.get("type")))
                chans = {c.name for c in header.get("channels", ())}
                declared.append((str(header.get("name", f"part {index}")), chans, _window(header.get("dataWindow"))))
        except (RuntimeError, ValueError, TypeError, IndexError, KeyError) as exc:
            raise DamagedFileError(
                f"{path}: the OpenEXR header cannot be read ({_first_reason([str(exc)], 'unknown error')}); "
                f"the file is truncated or damaged: {_REDO}"
            ) from None
    if deep:
        index, name, kind = deep[0]
        kind_name = "deep tiled" if kind == OpenEXR.deeptile else "deep scanline"
        where = f"part {index} {name!r} is" if len(declared) > 1 else "the image is"
        more = f" ({len(deep)} of its {len(declared)} parts are deep)" if len(deep) > 1 else ""
        raise InputError(
            f"{path}: {where} a {kind_name} image{more}; SSS Lab reads flat (non-deep) multilayer EXRs: render the "
            "passes again with Blender's multilayer EXR output"
        )
    return declared


def read_layers(path: str | os.PathLike) -> ExrContents:
    """Read every channel of an EXR file (any number of parts) into float32 layers.

    The file's header is read first, and every part and channel it declares must come back
    complete, with the size of its data window: OpenEXR's reader leaves out a part whose
    pixels it cannot read (a truncated or damaged file) and only warns, so without this check a
    damaged file would pass for one without that pass. Raises FileNotFoundError for a missing
    file and ``DamagedFileError`` (a ValueError) naming the file, the part and what to do for a
    file that is not an OpenEXR file, is truncated or damaged, or whose parts differ in size or
    use subsampled channels, and ``InputError`` for a file holding deep parts (several samples per
    pixel: SSS Lab reads flat images only).
    """
    OpenEXR = _import_openexr()
    path = os.fspath(path)
    if not os.path.isfile(path):
        if os.path.isdir(path):
            raise InputError(f"{path}: is a folder; expected a multilayer EXR file")
        if os.path.exists(path):  # a pipe, a device, a socket: reading it could block or never end
            raise InputError(f"{path}: is not a regular file (a pipe or a device); expected a multilayer EXR file")
        raise FileNotFoundError(f"{path}: no such EXR file")
    declared = _declared_parts(OpenEXR, path)
    with _collect_stderr() as lines:
        try:
            exr = OpenEXR.File(path, separate_channels=True)
            read = [(exr.header(i), exr.channels(i)) for i in range(len(exr.parts))]
        except (RuntimeError, ValueError, TypeError, IndexError, KeyError) as exc:
            raise DamagedFileError(
                f"{path}: the pixels cannot be read ({_first_reason(lines + [str(exc)], 'unknown error')}); "
                f"the file is truncated or damaged: {_REDO}"
            ) from None
    got = {str(h.get("name", f"part {i}")): (h, ch) for i, (h, ch) in enumerate(read)}
    for index, (name, chans, window) in enumerate(declared):
        where = f"part {index} {name!r}" if len(declared) > 1 else "the image"
        if name not in got or set(got[name][1]) != set(chans):
            reason = _first_reason(lines, "the reader returned no pixels for it")
            raise DamagedFileError(
                f"{path}: {where} cannot be read completely ({reason}); the file is truncated or damaged: {_REDO}"
            )
        if window is not None:
            expected = _window_size(window)
            for full, channel in got[name][1].items():
                if channel.pixels.shape[:2] != expected:
                    raise DamagedFileError(
                        f"{path}: {where} channel {full!r} read back {channel.pixels.shape[:2]} pixels; its header "
                        f"declares {expected}: the file is damaged: {_REDO}"
                    )
    grouped: dict[str, dict[str, np.ndarray]] = {}
    half: set[str] = set()
    types: dict[str, set] = {}
    shape = None
    header: dict = {}
    data_window = display_window = None
    for index, (part_header, part_channels) in enumerate(read):
        if index == 0:
            header = _user_header(part_header)
            data_window = _window(part_header.get("dataWindow"))
            display_window = _window(part_header.get("displayWindow"))
        elif _window(part_header.get("dataWindow")) != data_window:
            raise InputError(
                f"{path}: part {index} {part_header.get('name')!r} has the data window "
                f"{_window(part_header.get('dataWindow'))}, the first part {data_window}: SSS Lab needs every pass "
                "over the same pixels; render the passes again into one file"
            )
        for full, channel in part_channels.items():
            if (channel.xSampling, channel.ySampling) != (1, 1):
                raise InputError(f"{path}: channel {full!r} is subsampled; SSS Lab reads full-resolution channels only")
            pixels = channel.pixels
            if pixels.ndim != 2:
                raise InputError(f"{path}: channel {full!r} has shape {pixels.shape}; expected (height, width)")
            if shape is None:
                shape = pixels.shape
            elif pixels.shape != shape:
                raise InputError(f"{path}: channel {full!r} is {pixels.shape}, other channels are {shape}")
            layer, letter = split_channel(full)
            if pixels.dtype == np.float16:
                half.add(layer)
            types.setdefault(layer, set()).add(_type_name(pixels))
            grouped.setdefault(layer, {})[letter] = pixels
    if not grouped:
        raise InputError(f"{path}: the file holds no channels; pass the multilayer EXR that Blender rendered")
    layers: dict[str, np.ndarray] = {}
    channels: dict[str, tuple[str, ...]] = {}
    for layer, by_letter in grouped.items():
        order = _order_channels(by_letter)
        if len(order) == 1:
            arr = np.ascontiguousarray(by_letter[order[0]], dtype=np.float32)
        else:
            arr = np.stack([np.asarray(by_letter[c], dtype=np.float32) for c in order], axis=-1)
        arr.flags.writeable = False
        layers[layer] = arr
        channels[layer] = order
    return ExrContents(
        path=path,
        layers=layers,
        channels=channels,
        header=header,
        parts=len(read),
        half=half,
        types={k: frozenset(v) for k, v in types.items()},
        data_window=data_window,
        display_window=display_window,
    )


class MissingPassError(SSSLabError, KeyError):
    """A pass a computation needs is not in the file; the message says how to enable it."""

    def __str__(self) -> str:  # KeyError would print the repr of the message
        return str(self.args[0]) if self.args else ""


class Passes(Mapping):
    """The passes of one view layer: canonical (Blender 5.x) pass name -> float32 array.

    Arrays are (H, W) for one channel, (H, W, C) otherwise, rows top to bottom, read-only
    (techniques must not mutate their inputs). Build one from arrays directly (tests, the
    Blender operator) or with ``read_passes``.
    """

    def __init__(
        self,
        arrays: Mapping[str, np.ndarray],
        *,
        header: Mapping | None = None,
        view_layer: str = "ViewLayer",
        source: str = "",
        layout: str = "",
        half: Iterable[str] = (),
    ):
        if not arrays:
            raise ValueError(f"{source or 'passes'}: no passes in view layer {view_layer!r}")
        self._arrays: dict[str, np.ndarray] = {}
        shape = None
        for name, value in arrays.items():
            arr = np.asarray(value)
            if arr.ndim not in (2, 3):
                raise ValueError(f"pass {name!r}: expected shape (H, W) or (H, W, C), got {arr.shape}")
            if shape is None:
                shape = arr.shape[:2]
            elif arr.shape[:2] != shape:
                raise ValueError(f"pass {name!r}: size {arr.shape[:2]} differs from the other passes' {shape}")
            if arr.dtype != np.float32 or arr.flags.writeable:
                arr = np.array(arr, dtype=np.float32)  # a private float32 copy, even of half input
                arr.flags.writeable = False
            self._arrays[name] = arr
        self._shape: tuple[int, int] = (int(shape[0]), int(shape[1])) if shape is not None else (0, 0)
        self.header = dict(header or {})
        self.view_layer = view_layer
        self.source = source
        self.layout = layout
        #: Canonical names of passes that were stored as half floats in the file.
        self.half = frozenset(half)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._arrays[name]
        except KeyError:
            raise MissingPassError(self._missing_message(name, None)) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._arrays)

    def __len__(self) -> int:
        return len(self._arrays)

    def __repr__(self) -> str:
        return f"Passes({self.source or '<arrays>'}, view layer {self.view_layer!r}, {self._shape}, {list(self.names)})"

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._arrays)

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        return self._shape

    def _missing_message(self, name: str, why: str | None) -> str:
        where = f"{self.source}: " if self.source else ""
        need = f" ({why} needs it)" if why else ""
        return (
            f"{where}the pass {name!r} is missing from view layer {self.view_layer!r}{need}. "
            f"Enable it in Blender: {pass_hint(name)}, then render again. "
            f"Passes present: {', '.join(self.names)}"
        )

    def require(self, name: str, why: str) -> np.ndarray:
        """The pass ``name``, or MissingPassError naming it, what needs it and how to enable it."""
        if name not in self._arrays:
            raise MissingPassError(self._missing_message(name, why))
        return self._arrays[name]


#: Passes that hold integers and may be stored as UINT channels.
_INTEGER_PASSES = frozenset({"Object Index", "Material Index"})


def expected_channels(pass_name: str) -> tuple[frozenset, frozenset] | None:
    """(channel letters a known pass must have, letters it may have besides), or None for passes
    SSS Lab does not know (AOVs, light groups), whose channels are taken as they are."""
    letters = PASS_CHANNELS.get(pass_name)
    if letters is None:
        return None
    if letters == "RGB":  # a colour pass may carry an alpha channel besides
        letters = "RGBA"
    optional = frozenset("A") if "A" in letters else frozenset()
    return frozenset(letters) - optional, optional


def _check_pass(contents: ExrContents, layer: str, pass_name: str) -> None:
    """A known pass must have its channels and (but for the index passes) float pixels."""
    want = expected_channels(pass_name)
    if want is None or layer not in contents.channels:
        return
    required, optional = want
    have = contents.channels[layer]
    missing = sorted(required - set(have))
    if missing:
        raise InputError(
            f"{contents.path}: layer {layer!r} has the channels {', '.join(have)}; the {pass_name} pass needs "
            f"{', '.join(sorted(required))} (missing {', '.join(missing)}). The file was edited or written by another "
            "program: render the passes again with Blender's multilayer EXR output"
        )
    if pass_name not in _INTEGER_PASSES and "UINT" in contents.types.get(layer, ()):
        raise InputError(
            f"{contents.path}: layer {layer!r} is stored as UINT (integer) channels; the {pass_name} pass needs "
            "HALF or FLOAT channels. Save it as a float EXR (Blender: Output Properties > Output > Color Depth)"
        )


def passes_from_contents(contents: ExrContents, view_layer: str | None = None) -> Passes:
    """The ``Passes`` of one view layer of a file read by ``read_layers``.

    ``view_layer`` None picks the first view layer in the file that is not an SSS Lab output.
    Blender 4.x short pass names are renamed to the 5.x names unless the 5.x name is also
    present; a channel without any layer name (a plain RGBA image) is the Combined pass.
    """
    names = contents.view_layers
    if view_layer is None:
        inputs = [v for v in names if v != OUTPUT_PREFIX and not v.startswith(OUTPUT_PREFIX + ".")]
        if not inputs:
            raise ValueError(f"{contents.path}: only SSS Lab output layers in the file ({', '.join(names)})")
        view_layer = inputs[0]
    elif view_layer not in names:
        raise ValueError(f"{contents.path}: no view layer {view_layer!r}; the file has: {', '.join(names)}")
    raw = {}
    half = set()
    for layer, arr in contents.layers.items():
        vl, pass_name = split_layer(layer)
        if vl == view_layer:
            raw[pass_name or "Combined"] = (arr, layer in contents.half, layer)
    arrays = {}
    for name, (arr, was_half, layer) in raw.items():
        canonical = SHORT_PASS_NAMES.get(name, name)
        if canonical != name and canonical in raw:
            canonical = name
        _check_pass(contents, layer, canonical)
        have = contents.channels.get(layer)
        if PASS_CHANNELS.get(canonical) == "RGB" and have and len(have) > 3 and arr.ndim == 3:
            # A colour pass saved with an alpha channel besides: the passes read its RGB.
            arr = arr[..., [list(have).index(c) for c in "RGB"]]
        arrays[canonical] = arr
        if was_half:
            half.add(canonical)
    layout = (
        f"multi-part, one part per pass ({contents.parts} parts, Blender 5.x)"
        if contents.parts > 1
        else "single part (Blender 4.x)"
    )
    return Passes(arrays, header=contents.header, view_layer=view_layer, source=contents.path, layout=layout, half=half)


def read_passes(path: str | os.PathLike, view_layer: str | None = None) -> Passes:
    """Read the passes of one view layer of a Blender multilayer EXR (5.2 or 4.5 layout).

    Returns ``Passes``: canonical pass name -> float32 (H, W) or (H, W, C), rows top to bottom.
    """
    return passes_from_contents(read_layers(path), view_layer)


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def _box(window: Window) -> tuple[np.ndarray, np.ndarray]:
    return np.array(window[:2], np.int32), np.array(window[2:], np.int32)


def write_layers(
    path: str | os.PathLike,
    layers: Mapping[str, np.ndarray],
    header: Mapping | None = None,
    *,
    channels: Mapping[str, Iterable[str]] | None = None,
    overwrite: bool = False,
    inputs: Iterable[str | os.PathLike] = (),
    windows: tuple[Window, Window] | None = None,
) -> str:
    """Write ``layers`` as a multilayer EXR, one part per layer as Blender 5.2 does.

    ``layers`` maps full layer names (``'ViewLayer.Diffuse Direct'``, ``'SSSLab.burley.Image'``)
    to arrays (H, W) or (H, W, C) with rows top to bottom; all the same size. Channel letters
    come from ``channels[name]`` or ``default_channels``. Pixels are written as float32 whatever
    their dtype (half input is widened; values are never clamped). ``header`` holds descriptive
    attributes (str, int, float) written to the first part; structural keys are ignored.

    The file is written to a temporary file in the same folder and moved into place with
    ``os.replace``, so readers never see a partial file. An existing ``path`` raises
    FileExistsError unless ``overwrite``; a ``path`` that is one of ``inputs`` is never
    replaced, even with ``overwrite``. ``windows`` (data window, display window), as
    ``ExrContents.windows`` gives them, keeps an input's placement (a render border or crop); the
    data window must be the layers' size. By default both are (0, 0)..(W - 1, H - 1). Returns the
    path written.
    """
    OpenEXR = _import_openexr()
    path = os.fspath(path)
    for source in inputs:
        if os.path.exists(path) and _same_file(path, os.fspath(source)):
            raise FileExistsError(f"{path} is an input of this computation; refusing to overwrite it")
    if os.path.exists(path) and not overwrite:
        raise FileExistsError(f"{path} already exists; refusing to overwrite it (choose another output name)")
    if not layers:
        raise ValueError(f"{path}: no layers to write")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"{path}: the folder {folder} does not exist")
    channels = dict(channels or {})
    shape = None
    parts = []
    for index, (name, value) in enumerate(layers.items()):
        if not isinstance(name, str) or not name or name.endswith("."):
            raise ValueError(f"layer name {name!r}: expected a non-empty name like 'ViewLayer.Combined'")
        arr = np.asarray(value)
        if arr.ndim == 2:
            arr = arr[:, :, None]
        if arr.ndim != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
            raise ValueError(f"layer {name!r}: expected shape (H, W) or (H, W, C), got {np.shape(value)}")
        if shape is None:
            shape = arr.shape[:2]
        elif arr.shape[:2] != shape:
            raise ValueError(f"layer {name!r}: size {arr.shape[:2]} differs from the other layers' {shape}")
        if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
            raise ValueError(f"layer {name!r}: expected numbers, got dtype {arr.dtype}")
        letters = tuple(channels.get(name) or default_channels(name, arr.shape[2]))
        if len(letters) != arr.shape[2] or len(set(letters)) != len(letters):
            raise ValueError(f"layer {name!r}: channel letters {letters} do not fit {arr.shape[2]} channels")
        pixels = {
            f"{name}.{letter}": np.ascontiguousarray(arr[:, :, c], dtype=np.float32) for c, letter in enumerate(letters)
        }
        part_header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        if windows is not None:
            data_window, display_window = windows
            if _window_size(data_window) != shape:
                raise ValueError(f"windows: the data window {data_window} is not the layers' size {shape}")
            part_header["dataWindow"] = _box(data_window)
            part_header["displayWindow"] = _box(display_window)
        if index == 0 and header:
            part_header.update(_user_header(header))
        parts.append(OpenEXR.Part(part_header, pixels, name))
    atomic_write(path, lambda tmp: OpenEXR.File(parts).write(tmp), overwrite=overwrite)
    return path

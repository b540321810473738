"""Stratus from Python: GFS forecasts to cloud maps as xarray Datasets, and headless renders.

The functions run the ``stratus`` command line's own code (``stratus._native``, built from the
repository with ``pip install ./python``), so their arguments, defaults, pictures and errors are
the command's:

- :func:`ingest` — ``stratus ingest FILE… --region S,N,W,E --size WxH --out STORE.zarr``, as an
  ``xarray.Dataset`` with the store's variables, coordinates and attributes;
- :func:`open` — a Zarr store, a PNG map (its ``.json`` sidecar or its ``.png``) or a series
  sidecar, as a Dataset;
- :func:`render` — ``stratus render``: the picture as a NumPy ``uint8`` array (H, W, 4);
- :func:`score` — ``stratus score --json``: the report as a dict.

A bad argument or input raises ``ValueError``, a file that cannot be read or written
``OSError``; the message is the line ``stratus`` prints after ``error:``.
See docs/python.md.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
import xarray as xr

from . import _native

__version__: str = _native.__version__

__all__ = ["ingest", "open", "render", "score", "__version__"]

PathLike = Union[str, "os.PathLike[str]"]
#: A moment: an ISO 8601 text (``2015-09-12T21:00:00Z``; no zone is UTC), a ``datetime``
#: (naive is UTC) or a ``numpy.datetime64`` (UTC, as xarray's decoded times are).
Time = Union[str, _dt.datetime, np.datetime64]
#: ``--camera``'s altitude: metres above sea level, or ``"ground"`` / ``"ground+N"``.
Altitude = Union[float, str]


def _num(x: Any, what: str) -> str:
    """A number as the command line reads it back exactly (``repr`` of a float round-trips)."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what}: {x!r} is not a number")
    return repr(float(x)) if isinstance(x, (float, np.floating)) else str(int(x))


def _numbers(xs: Sequence[Any], n: int, what: str) -> str:
    if isinstance(xs, str) or len(xs) != n:
        raise ValueError(f"{what} must be {n} numbers, got {xs!r}")
    return ",".join(_num(x, what) for x in xs)


def _size(size: Any, what: str) -> str:
    if isinstance(size, str):
        return size
    if len(size) != 2:
        raise ValueError(f"{what} must be (W, H), got {size!r}")
    return f"{_num(size[0], what)}x{_num(size[1], what)}"


def _time(t: Time) -> str:
    if isinstance(t, str):
        return t
    if isinstance(t, np.datetime64):
        return str(np.datetime_as_string(t.astype("datetime64[s]"), unit="s")) + "Z"
    if isinstance(t, _dt.datetime):
        if t.tzinfo is not None:
            t = t.astimezone(_dt.timezone.utc).replace(tzinfo=None)
        return t.isoformat(timespec="seconds") + "Z"
    raise ValueError(f"time {t!r} is neither ISO 8601 text, a datetime nor a numpy.datetime64")


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _options(opts: Dict[str, Any]) -> List[str]:
    """Keyword options as the command's flags: ``rh_cr_low=0.8`` → ``--rh-cr-low 0.8``;
    ``True`` a bare flag, ``None``/``False`` left out, a sequence comma-joined."""
    argv: List[str] = []
    for k, v in opts.items():
        if v is None or v is False:
            continue
        if v is True:
            argv.append(_flag(k))
            continue
        if isinstance(v, (list, tuple)):
            v = ",".join(str(x) if isinstance(x, str) else _num(x, _flag(k)) for x in v)
        elif isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
            v = _num(v, _flag(k))
        elif isinstance(v, (_dt.datetime, np.datetime64)):
            v = _time(v)
        argv += [_flag(k), os.fspath(v) if isinstance(v, os.PathLike) else str(v)]
    return argv


def _dataset(arrays: Tuple[str, list]) -> xr.Dataset:
    """The native side's arrays as the Dataset ``xarray.open_zarr`` gives for the store."""
    group_attrs, items = arrays
    variables = {}
    for name, dims, dtype, shape, data, attrs in items:
        values = np.frombuffer(data, dtype=np.dtype(dtype).newbyteorder("<")).reshape(shape)
        variables[name] = xr.Variable(tuple(dims), values.copy(), json.loads(attrs))
    ds = xr.Dataset(variables, attrs=json.loads(group_attrs))
    # The CF decoding open_zarr applies: scale and offset, _FillValue, times.
    return xr.decode_cf(ds)


def ingest(
    files: Union[PathLike, Iterable[PathLike]],
    region: Sequence[float],
    size: Sequence[int] = (1024, 1024),
    *,
    level: Optional[float] = None,
    top_hpa: Optional[float] = None,
    rh_cr: Optional[float] = None,
    rh_cr_low: Optional[float] = None,
    rh_cr_mid: Optional[float] = None,
    rh_cr_high: Optional[float] = None,
    interp: Optional[str] = None,
    store: Optional[PathLike] = None,
) -> xr.Dataset:
    """Ingest GFS GRIB2 forecast file(s) into a CloudMap Dataset.

    Runs ``stratus ingest FILES… --region S,N,W,E --size WxH --out STORE.zarr`` into a
    temporary store and reads it back whole: the Dataset has the store's variables,
    dimensions, coordinates and attributes (docs/zarr.md), decoded as ``xarray.open_zarr``
    decodes them. Several steps of one run (several files, or one file holding several) give a
    ``time`` axis of several steps.

    Args:
        files: one GRIB2 file or several steps of one run.
        region: (south, north, west, east) in degrees; west > east crosses the date line.
        size: (width, height) in pixels.
        level: one isobaric level in hPa instead of all levels folded into layers.
        top_hpa: highest level (lowest pressure, hPa) folded into the layers (default 100).
        rh_cr: critical humidity of every layer; ``rh_cr_low``/``_mid``/``_high`` one each.
        interp: ``spline``, ``catmull-rom``, ``bilinear`` or ``nearest``.
        store: keep the Zarr store here (a new ``*.zarr`` path; an existing one is refused, as
            the command refuses it) for :func:`render`, :func:`score` or ``xarray.open_zarr``;
            by default it is written to a temporary folder and removed.

    Raises:
        ValueError: bad arguments or a file that is not a usable forecast.
        OSError: a file that cannot be read.
    """
    if isinstance(files, (str, os.PathLike)):
        files = [files]
    argv = [os.fspath(f) for f in files]
    argv += ["--region", _numbers(region, 4, "region (S, N, W, E)"), "--size", _size(size, "size")]
    argv += _options(
        dict(
            level=level,
            top_hpa=top_hpa,
            rh_cr=rh_cr,
            rh_cr_low=rh_cr_low,
            rh_cr_mid=rh_cr_mid,
            rh_cr_high=rh_cr_high,
            interp=interp,
        )
    )
    if store is not None:
        _native.ingest(argv, os.fspath(store))
        return _dataset(_native.open(os.fspath(store)))
    with tempfile.TemporaryDirectory(prefix="stratus-ingest-") as d:
        tmp = Path(d) / "map.zarr"
        _native.ingest(argv, str(tmp))
        return _dataset(_native.open(str(tmp)))


def open(path: PathLike) -> xr.Dataset:  # noqa: A001 - the issue's name
    """Open what ``stratus`` writes as a Dataset.

    ``path`` is a Zarr store (``STORE.zarr``), a PNG map (its ``MAP.json`` sidecar, or
    ``MAP.png`` beside it) or a series sidecar (``NAME.json``). Every kind gives the store's
    variables and coordinates; a PNG map or series is laid out as a store of the same steps
    would be (its ``history`` attribute says where it was read from). The arrays are read
    whole into memory.

    Raises:
        ValueError: a file that is not a CloudMap, series or store, or is damaged.
        OSError: a file that cannot be read.
    """
    p = os.fspath(path)
    if p.lower().endswith(".png"):
        p = str(Path(p).with_suffix(".json"))
    return _dataset(_native.open(p))


def render(
    map: PathLike,  # noqa: A002 - the issue's name
    camera: Optional[Tuple[float, float, Altitude]] = None,
    *,
    heading: float = 0.0,
    pitch: float = 0.0,
    fov: float = 60.0,
    size: Sequence[int] = (1280, 720),
    preset: str = "balanced",
    time: Optional[Time] = None,
    top_down: bool = False,
    **options: Any,
) -> np.ndarray:
    """Render one frame of a CloudMap, series or store, headless.

    Runs ``stratus render --map MAP --camera LAT,LON,ALT_M --heading … --pitch … --size WxH
    --preset … [--time …]`` without ``--out`` and returns the frame's pixels, read back from
    the renderer (no file is written): a ``uint8`` array of shape (height, width, 4), RGBA,
    equal pixel for pixel to the PNG the command writes.

    Args:
        map: the ``--map`` (a map's sidecar, a series sidecar or a store).
        camera: (latitude, longitude, altitude): metres above sea level, or ``"ground"`` /
            ``"ground+N"`` (N metres above the map's terrain). Or ``top_down=True``.
        heading, pitch, fov: degrees (clockwise from north; up from the horizon; vertical).
        size: (width, height) in pixels.
        preset: ``fast``, ``balanced``, ``high`` or ``reference``.
        time: the Sun's moment and, for a series, the weather's (blended between steps).
        **options: any other ``stratus render`` flag by name (``exposure="0"``,
            ``layers="low,middle"``, ``visibility_km=30``, ``render_scale=0.5``, ``adapter=…``).

    Raises:
        ValueError: bad arguments (the command's text), a camera below the ground…
        OSError: a map that cannot be read.
    """
    argv = ["--map", os.fspath(map)]
    if camera is not None:
        if isinstance(camera, str) or len(camera) != 3:
            raise ValueError(f"camera must be (lat, lon, alt_m), got {camera!r}")
        lat, lon, alt = camera
        alt_s = alt if isinstance(alt, str) else _num(alt, "camera altitude")
        argv += ["--camera", f"{_num(lat, 'camera latitude')},{_num(lon, 'camera longitude')},{alt_s}"]
    argv += _options(
        dict(
            top_down=top_down,
            heading=heading,
            pitch=pitch,
            fov=fov,
            size=_size(size, "size"),
            preset=preset,
            time=None if time is None else _time(time),
            **options,
        )
    )
    os.environ.setdefault("NODEVICE_SELECT", "1")
    data, w, h = _native.render(argv)
    return np.frombuffer(data, dtype=np.uint8).reshape(h, w, 4).copy()


def score(
    map: PathLike,  # noqa: A002 - the issue's name
    *,
    preset: str = "balanced",
    time: Optional[Time] = None,
    score_size: Optional[Sequence[int]] = None,
    block: Optional[int] = None,
    render_threshold: Optional[float] = None,
    map_threshold: Optional[float] = None,
    diff: Optional[PathLike] = None,
    **options: Any,
) -> Dict[str, Any]:
    """Score a top-down render against the map: ``stratus score --map MAP --json``.

    Returns the command's JSON report as a dict: ``map``, ``preset``, ``width``, ``height``,
    ``block``, ``mask_width``, ``mask_height``, ``render_threshold``, ``map_threshold``,
    ``total`` and ``layers`` (each with ``layer``, ``dice``, ``iou``, ``precision``,
    ``recall``, ``render_px``, ``map_px``, ``both_px``, ``total_px`` and ``note``).

    Args:
        map: a map's sidecar, a series sidecar (``time`` picks the moment) or a store.
        score_size: (width, height) of the render (default: the map's, at most 1024).
        diff: write the total's diff picture to this PNG.
        **options: any other ``stratus score`` flag by name (``layers=…``, ``coverage=…``).

    Raises:
        ValueError / OSError: as :func:`render`.
    """
    argv = ["--map", os.fspath(map)]
    argv += _options(
        dict(
            preset=preset,
            time=None if time is None else _time(time),
            score_size=None if score_size is None else _size(score_size, "score_size"),
            block=block,
            render_threshold=render_threshold,
            map_threshold=map_threshold,
            diff=None if diff is None else os.fspath(diff),
            **options,
        )
    )
    os.environ.setdefault("NODEVICE_SELECT", "1")
    return json.loads(_native.score(argv))

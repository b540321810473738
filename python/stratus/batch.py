"""Ingest GRIB2 forecasts into one Zarr v3 CloudMap store on a Dask cluster (issue 32).

``stratus.batch.ingest(files, store, region=(S, N, W, E), size=(W, H), client=None)`` and
``python -m stratus.batch FILES... --out STORE.zarr --region S N W E --size W H
[--scheduler ADDRESS] [--workers N]`` write the store a serial
``stratus ingest FILES... --out STORE.zarr`` writes, chunk for chunk, in four phases of
``stratus ingest`` calls (docs/zarr.md, "Batch"):

1. ``--plan`` (here, once): the store's metadata for every step, from the files' headers
   (time axis, lattices, coordinates), and the run's lock ``.STORE.zarr.batch/`` beside the
   store, created exclusively and holding the run's id: a second run on the store is refused;
2. one Dask task per forecast step (``--step K``): it writes time index K's chunks only;
3. one Dask task per interval (``--motion K``, after steps K and K + 1): the motion between
   the two steps, interval K's chunks only;
4. ``--finish`` (here, once): the store's series attributes; the run's lock released.

Each task runs the ``stratus`` binary as a subprocess and raises ``ValueError`` with its
one-line error when it fails (exit 2), ``RuntimeError`` otherwise; Dask retries a failed task
(``retries``) and reschedules one whose worker died. The binary is found, in this order, from
the environment variable ``STRATUS_BIN``, as ``target/release/stratus`` in the repository this
file lies in, then on ``PATH``; the client resolves it and every task runs that path (on a
cluster of other machines it must be there too: set ``STRATUS_BIN``).

Without a client (``--scheduler``) a ``distributed.LocalCluster`` of ``workers`` processes
(2 by default, one thread each) is started on this machine and closed after; with one, the
tasks run on that cluster (the files and the store must then be on a file system every
worker sees, at the same paths). Progress is ``distributed.progress``; the dashboard's link
is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path
from typing import Iterable, Optional, Sequence

__all__ = ["ingest", "find_stratus", "main"]


def find_stratus() -> str:
    """The ``stratus`` binary: ``$STRATUS_BIN``, else the repository's
    ``target/release/stratus``, else ``stratus`` on ``PATH``."""
    env = os.environ.get("STRATUS_BIN")
    if env:
        return env
    repo = Path(__file__).resolve().parents[2] / "target" / "release" / "stratus"
    if repo.is_file() and os.access(repo, os.X_OK):
        return str(repo)
    found = shutil.which("stratus")
    if found:
        return found
    raise FileNotFoundError(
        "stratus: binary not found (set STRATUS_BIN, build target/release/stratus, or put it on PATH)"
    )


def _stratus_ingest(exe: str, args: Sequence[str]) -> str:
    """Run ``stratus ingest ARGS``; its stdout, or the CLI's one-line error raised."""
    r = subprocess.run(
        [exe, "ingest", *args],
        capture_output=True,
        text=True,
        env={**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "error")},
    )
    if r.returncode != 0:
        lines = [l for l in r.stderr.strip().splitlines() if l.strip()]
        msg = lines[-1] if lines else f"stratus ingest exited with {r.returncode}"
        msg = msg.removeprefix("error: ")
        if r.returncode == 2:
            raise ValueError(msg)
        raise RuntimeError(f"{msg} (exit {r.returncode})")
    return r.stdout


def _step(exe: str, common: Sequence[str], store: str, k: int, run: str) -> str:
    """Dask task: step ``k`` of the planned store."""
    return _stratus_ingest(exe, [*common, "--out", store, "--step", str(k), "--run", run])


def _motion(exe: str, store: str, k: int, run: str, *_after) -> str:
    """Dask task: interval ``k`` (``_after``: the two steps' results, so it runs after them)."""
    return _stratus_ingest(exe, ["--out", store, "--motion", str(k), "--run", run])


def _region(region: Sequence[float]) -> str:
    s, n, w, e = region
    return f"{s:g},{n:g},{w:g},{e:g}"


def _planned_steps(store: str) -> int:
    with open(os.path.join(store, "zarr.json"), encoding="utf-8") as f:
        return len(json.load(f)["attributes"]["stratus_plan"]["hours"])


def ingest(
    files: Iterable[str | os.PathLike],
    store: str | os.PathLike,
    region: Sequence[float],
    size: Sequence[int],
    client=None,
    *,
    workers: int = 2,
    retries: int = 3,
    options: Sequence[str] = (),
    progress: bool = True,
) -> str:
    """Write the forecast steps of ``files`` as the new Zarr store ``store`` on a Dask cluster.

    ``region`` is (south, north, west, east) in degrees, ``size`` (width, height) in pixels;
    ``options`` are further ``stratus ingest`` arguments (e.g. ``["--rh-cr", "0.8,0.75,0.7"]``),
    given to every call. ``client`` is a ``distributed.Client``; ``None`` starts a local
    cluster of ``workers`` processes for the call. Each task is retried ``retries`` times.
    Returns the store's path. Raises ``ValueError`` with the CLI's one-line error (a store
    that exists, another batch run on it, bad input); the store and its run lock are removed
    when a run that planned it fails.
    """
    from distributed import Client, LocalCluster
    from distributed import progress as show_progress

    exe = find_stratus()
    store = os.path.abspath(os.fspath(store))
    common = [os.path.abspath(os.fspath(f)) for f in files]
    common += ["--region", _region(region), "--size", f"{int(size[0])}x{int(size[1])}"]
    common += list(options)
    run = uuid.uuid4().hex
    _stratus_ingest(exe, [*common, "--out", store, "--plan", "--run", run])
    cluster = own = None
    futures: list = []
    try:
        n = _planned_steps(store)
        if client is None:
            cluster = LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
            )
            client = own = Client(cluster)
        print(f"stratus.batch: dashboard {client.dashboard_link}", file=sys.stderr)
        steps = [
            client.submit(
                _step, exe, common, store, k, run, key=f"stratus-step-{k}-{run}", retries=retries
            )
            for k in range(n)
        ]
        motions = [
            client.submit(
                _motion,
                exe,
                store,
                k,
                run,
                steps[k],
                steps[k + 1],
                key=f"stratus-motion-{k}-{run}",
                retries=retries,
            )
            for k in range(n - 1)
        ]
        futures = steps + motions
        if progress:
            show_progress(futures)
        client.gather(futures)
        _stratus_ingest(exe, ["--out", store, "--finish", "--run", run])
    except BaseException:
        # This run planned the store: nothing of it is left for a later run to trip on (a
        # call still running finds the store gone and writes nothing more).
        if futures:
            client.cancel(futures)
        shutil.rmtree(store, ignore_errors=True)
        lock = Path(store).with_name(f".{Path(store).name}.batch")
        shutil.rmtree(lock, ignore_errors=True)
        raise
    finally:
        if own is not None:
            own.close()
        if cluster is not None:
            cluster.close()
    return store


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m stratus.batch``: see the module's docstring. Arguments after ``--`` are
    given to every ``stratus ingest`` call."""
    argv = list(sys.argv[1:] if argv is None else argv)
    extra: list[str] = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1 :]
    p = argparse.ArgumentParser(
        prog="python -m stratus.batch",
        description="Ingest GRIB2 forecast steps into one Zarr v3 store on a Dask cluster.",
    )
    p.add_argument("files", nargs="+", help="GRIB2 forecast files (the steps of one run)")
    p.add_argument("--out", required=True, help="the new store, STORE.zarr")
    p.add_argument("--region", nargs=4, type=float, required=True, metavar=("S", "N", "W", "E"))
    p.add_argument("--size", nargs=2, type=int, required=True, metavar=("W", "H"))
    p.add_argument("--scheduler", help="a Dask scheduler's address (default: a local cluster)")
    p.add_argument("--workers", type=int, default=2, help="local cluster's worker processes")
    p.add_argument("--retries", type=int, default=3, help="retries of each task")
    a = p.parse_args(argv)
    client = None
    try:
        if a.scheduler:
            from distributed import Client

            client = Client(a.scheduler)
        out = ingest(
            a.files,
            a.out,
            a.region,
            a.size,
            client,
            workers=a.workers,
            retries=a.retries,
            options=extra,
        )
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (OSError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    finally:
        if client is not None:
            client.close()
    print(f"{out}: written")
    return 0


if __name__ == "__main__":
    sys.exit(main())

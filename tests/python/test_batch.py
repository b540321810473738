"""Ingest on a Dask cluster (issue 32, python/stratus/batch.py): a local cluster of 2 worker
processes writes, for every real series here (the 2.5 deg North Atlantic pair, the 0.25 deg
Poland triple), the store a serial ``stratus ingest --out`` writes, array for array and chunk
for chunk; a worker killed in the middle of a step (its task rescheduled) gives the same
store; two batch runs racing on one store: one is refused, the store is the other's, whole.

``stratus.batch`` is imported from a copy of python/stratus/batch.py beside a docstring-only
``__init__.py`` (the native package need not be built), on ``PYTHONPATH`` so that the Dask
worker processes import it too. Run by scripts/python-tests.sh.
"""

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

ROOT = Path(__file__).resolve().parents[2]
NA = {
    "files": [ROOT / "data-samples" / "gfs-series" / f"gfs.t18z.pgrb2.2p50.{f}" for f in ("f000", "f006")],
    "region": (30, 65, -60, 10),
    "size": (200, 100),
}
PL = {
    "files": [
        ROOT / "data-samples" / "gfs-series-poland" / f"gfs.20200804.t12z.pgrb2.0p25.{f}"
        for f in ("f000", "f006", "f012")
    ],
    "region": (48, 56, 13, 25),
    "size": (180, 120),
}


def stratus():
    exe = Path(os.environ.get("STRATUS_BIN", ROOT / "target" / "release" / "stratus"))
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "stratus"], cwd=ROOT, check=True)
    return str(exe)


@pytest.fixture(scope="module")
def pkg(tmp_path_factory):
    """A folder holding the package ``stratus`` with only ``batch``."""
    d = tmp_path_factory.mktemp("pkg")
    (d / "stratus").mkdir()
    (d / "stratus" / "__init__.py").write_text('"""stratus.batch alone, for its tests."""\n')
    shutil.copy(ROOT / "python" / "stratus" / "batch.py", d / "stratus" / "batch.py")
    return d


def region_args(case):
    s, n, w, e = case["region"]
    return ["--region", f"{s},{n},{w},{e}", "--size", "{}x{}".format(*case["size"])]


def serial(case, out):
    r = subprocess.run(
        [stratus(), "ingest", *map(str, case["files"]), *region_args(case), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    return out


def batch(pkg, case, out, env=None, workers=2):
    """``python -m stratus.batch`` on a local cluster of ``workers`` processes: started."""
    s, n, w, e = case["region"]
    cmd = [sys.executable, "-m", "stratus.batch", *map(str, case["files"]), "--out", str(out)]
    cmd += ["--region", str(s), str(n), str(w), str(e), "--size", *map(str, case["size"])]
    cmd += ["--workers", str(workers)]
    full_env = {**os.environ, "PYTHONPATH": str(pkg), "STRATUS_BIN": stratus(), **(env or {})}
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=full_env)


def finished(p, timeout=600):
    out, err = p.communicate(timeout=timeout)
    return p.returncode, out, err


def files_of(store):
    return {
        str(f.relative_to(store)): f.read_bytes()
        for f in sorted(Path(store).rglob("*"))
        if f.is_file() and ".stratus-tmp" not in f.name
    }


def without_ids(group_bytes):
    attrs = json.loads(group_bytes)["attributes"]
    for m in attrs["stratus_steps"]:
        m.pop("image_id", None)  # a fresh id binds each ingest's PNG set: never equal
    return attrs


def assert_same_store(want, got):
    a, b = files_of(want), files_of(got)
    assert sorted(a) == sorted(b)
    for k in a:
        if k == "zarr.json":
            assert without_ids(a[k]) == without_ids(b[k])
        else:
            assert a[k] == b[k], k
    # And as xarray reads them: every variable, value for value.
    da = xr.open_zarr(want, consolidated=False, decode_cf=False)
    db = xr.open_zarr(got, consolidated=False, decode_cf=False)
    assert set(da.variables) == set(db.variables)
    assert {"coverage", "motion_u", "motion_v", "motion_scale"} <= set(da.variables)
    for v in da.variables:
        np.testing.assert_array_equal(da[v].values, db[v].values, err_msg=v)


@pytest.fixture(scope="module")
def serial_na(tmp_path_factory):
    return serial(NA, tmp_path_factory.mktemp("serial") / "na.zarr")


@pytest.mark.parametrize("case", [NA, PL], ids=["north-atlantic-2p5", "poland-0p25"])
def test_a_local_cluster_writes_the_serial_store(pkg, tmp_path, case):
    want = serial(case, tmp_path / "serial.zarr")
    code, out, err = finished(batch(pkg, case, tmp_path / "batch.zarr"))
    assert code == 0, err
    assert "dashboard http" in err
    assert_same_store(want, tmp_path / "batch.zarr")
    assert not (tmp_path / ".batch.zarr.batch").exists()


def test_a_worker_killed_mid_step_still_gives_the_store(pkg, tmp_path, serial_na):
    # The binary the tasks run kills its own Dask worker process (SIGKILL) while step 1 is
    # being written, once: Dask reschedules the task on a (restarted) worker.
    marker = tmp_path / "killed"
    wrapper = tmp_path / "stratus-killer"
    wrapper.write_text(
        f"""#!/bin/sh
case " $* " in *" --step 1 "*)
    if mkdir "{marker}" 2>/dev/null; then
        echo $PPID > "{marker}/worker"
        "{stratus()}" "$@" & child=$!
        sleep 0.3
        kill -9 $child $PPID
        exit 137
    fi;;
esac
exec "{stratus()}" "$@"
"""
    )
    wrapper.chmod(0o755)
    code, out, err = finished(batch(pkg, NA, tmp_path / "b.zarr", env={"STRATUS_BIN": str(wrapper)}))
    assert code == 0, err
    worker = int((marker / "worker").read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(worker, 0)  # that worker is gone
    assert_same_store(serial_na, tmp_path / "b.zarr")


def test_racing_batch_runs_one_is_refused_and_the_store_is_whole(pkg, tmp_path, serial_na):
    out = tmp_path / "race.zarr"
    runs = [batch(pkg, NA, out), batch(pkg, NA, out)]
    results = [finished(p) for p in runs]
    codes = sorted(c for c, _, _ in results)
    assert codes == [0, 2], results
    refused = next(err for c, _, err in results if c == 2)
    assert "another batch run" in refused or "it exists" in refused, refused
    assert len(refused.strip().splitlines()) == 1, refused
    assert_same_store(serial_na, out)
    # A third run on the finished store is refused and leaves it as it is.
    before = files_of(out)
    code, _, err = finished(batch(pkg, NA, out))
    assert code == 2 and "it exists" in err, err
    assert files_of(out) == before


def test_the_python_api_with_a_client(pkg, tmp_path, serial_na, monkeypatch):
    monkeypatch.syspath_prepend(str(pkg))
    monkeypatch.setenv("PYTHONPATH", str(pkg))
    monkeypatch.setenv("STRATUS_BIN", stratus())
    from distributed import Client, LocalCluster

    import stratus.batch as sb

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        with Client(c) as client:
            t = time.time()
            got = sb.ingest(NA["files"], tmp_path / "api.zarr", NA["region"], NA["size"], client, progress=False)
            assert time.time() - t < 600
            assert got == str(tmp_path / "api.zarr")
            # Bad input is the CLI's one line as ValueError; nothing is left behind.
            with pytest.raises(ValueError, match="it exists"):
                sb.ingest(NA["files"], got, NA["region"], NA["size"], client, progress=False)
    assert_same_store(serial_na, tmp_path / "api.zarr")


def test_a_step_that_fails_raises_its_line_and_leaves_nothing(pkg, tmp_path):
    wrapper = tmp_path / "stratus-failing"
    wrapper.write_text(
        f"""#!/bin/sh
case " $* " in *" --step 1 "*) echo "error: step 1: injected failure" >&2; exit 2;; esac
exec "{stratus()}" "$@"
"""
    )
    wrapper.chmod(0o755)
    out = tmp_path / "f.zarr"
    p = batch(pkg, NA, out, env={"STRATUS_BIN": str(wrapper)})
    code, _, err = finished(p)
    assert code == 2, err
    assert err.strip().splitlines()[-1] == "error: step 1: injected failure", err
    assert not out.exists() and not (tmp_path / ".f.zarr.batch").exists()

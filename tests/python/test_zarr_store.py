"""xarray opens a Zarr v3 store the CLI writes (issue 32), with no Stratus code: dimensions,
coordinates, CF times and attributes decode; values are the PNG map's samples scaled.

Run by scripts/python-tests.sh (the README's test command): it builds nothing itself but uses
target/release/stratus (or $STRATUS_BIN), building it with cargo when it is missing.
"""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

ROOT = Path(__file__).resolve().parents[2]
SERIES = ROOT / "data-samples" / "gfs-series"
REGION = ["--region", "30,65,-60,10", "--size", "600x300"]


def stratus():
    exe = Path(os.environ.get("STRATUS_BIN", ROOT / "target" / "release" / "stratus"))
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "stratus"], cwd=ROOT, check=True)
    return str(exe)


def ingest(files, out, *extra):
    r = subprocess.run(
        [stratus(), "ingest", *map(str, files), *REGION, "--out", str(out), *extra],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    out = tmp_path_factory.mktemp("zarr") / "na.zarr"
    ingest([SERIES / "gfs.t18z.pgrb2.2p50.f000"], out)
    ingest([SERIES / "gfs.t18z.pgrb2.2p50.f006"], out, "--append")
    return out


def test_dimensions_and_coordinates_decode(store):
    ds = xr.open_zarr(store, consolidated=False)
    assert ds.sizes["time"] == 2 and ds.sizes["layer"] == 3
    assert ds.sizes["lat"] == 300 and ds.sizes["lon"] == 600
    assert ds.coverage.dims == ("time", "layer", "lat", "lon")
    assert ds.total_coverage.dims == ("time", "lat", "lon")
    assert ds.cloud_base.dims == ("time", "layer", "structure_lat", "structure_lon")
    assert ds.surface_altitude.dims == ("time", "ground_lat", "ground_lon")
    # Pixel centres, north first: half a pixel inside the region.
    np.testing.assert_allclose(ds.lat.values[[0, -1]], [65 - 35 / 600, 30 + 35 / 600])
    np.testing.assert_allclose(ds.lon.values[[0, -1]], [-60 + 70 / 1200, 10 - 70 / 1200])
    assert ds.lat.attrs["units"] == "degrees_north"
    assert ds.lon.attrs["standard_name"] == "longitude"
    assert ds.layer.attrs["flag_meanings"] == "low middle high"


def test_times_decode_as_valid_times(store):
    ds = xr.open_zarr(store, consolidated=False)
    assert ds.time.dtype.kind == "M"
    want = np.array(["2015-09-12T18:00", "2015-09-13T00:00"], dtype="datetime64[ns]")
    np.testing.assert_array_equal(ds.time.values, want)
    np.testing.assert_array_equal(ds.forecast_period.values, [0.0, 6.0])


def test_attributes_decode(store):
    ds = xr.open_zarr(store, consolidated=False)
    assert ds.attrs["reference_time"] == "2015-09-12T18:00:00Z"
    assert ds.attrs["format_version"] == 1
    assert ds.attrs["stratus_format"] == "stratus-zarr/1"
    assert set(ds.attrs["rh_cr"]) == {"low", "middle", "high"}
    assert len(ds.attrs["source_files"]) == 2
    assert ds.coverage.attrs["standard_name"] == "cloud_area_fraction_in_atmosphere_layer"
    assert ds.total_coverage.attrs["standard_name"] == "cloud_area_fraction"
    assert ds.cloud_base.attrs["units"] == "m"
    assert ds.eastward_wind.attrs["standard_name"] == "eastward_wind"
    meanings = ds.cloud_type.attrs["flag_meanings"].split()
    assert meanings[0] == "none" and meanings[-1] == "cumulonimbus"
    assert list(ds.cloud_type.attrs["flag_values"]) == list(range(len(meanings)))


def test_values_are_the_maps_samples_scaled(store):
    ds = xr.open_zarr(store, consolidated=False)
    cov = ds.coverage.values
    assert 0.0 <= cov.min() and cov.max() <= 1.0 and cov.max() > 0.5
    # The total is the max of the layers (the PNG's A channel), to the sample.
    np.testing.assert_allclose(ds.total_coverage.values, cov.max(axis=1), atol=1 / 65535)
    raw = xr.open_zarr(store, consolidated=False, mask_and_scale=False)
    np.testing.assert_allclose(cov, raw.coverage.values / 65535.0)
    base = ds.cloud_base.values
    top = ds.cloud_top.values
    both = ~np.isnan(base) & ~np.isnan(top)
    assert both.any() and (top[both] >= base[both]).all()
    assert np.nanmin(base) >= -500 and np.nanmax(top) < 33000
    u = ds.eastward_wind.values
    assert np.isfinite(u).all() and np.abs(u).max() < 150

//! `stratus._native`: the Python package's native module (docs/python.md). Thin: each function
//! takes the command line's own arguments, parsed by the command line's own clap structs, and
//! runs the command line's own code, so Python and `stratus` cannot disagree on defaults,
//! checks, pictures or error texts:
//!
//! - `ingest`: `stratus ingest … --out STORE.zarr` into a store the caller names (the Zarr
//!   writer, `stratus_ingest::zarr::write::create`), read back by [`dataset`];
//! - `open`: a store, a PNG map or a series sidecar as plain arrays ([`dataset`]);
//! - `render`: `stratus render` itself (`src/cmd/render.rs`, `frame`): the pixels it would
//!   write to PNG, handed back directly;
//! - `score`: `stratus score`'s report (`src/cmd/score.rs`) as JSON.
//!
//! Errors are one line, the text `stratus` prints after `error: `; a file that cannot be read
//! or written raises `OSError`, anything else `ValueError` ([`to_py`]).

use std::path::PathBuf;

use clap::Parser;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use stratus_ingest::error::IngestError;

mod dataset;

// The binary's command-line modules, compiled in as they are (not copied): every Python call
// goes through the code `stratus` runs. Only some of them are called from here.
#[macro_use]
#[allow(dead_code, unused_imports, unused_macros)]
#[path = "../../src/cmd/mod.rs"]
mod cmd;

/// One line, as `stratus` prints it (without `error: `), as the Python exception it maps to.
fn to_py(e: anyhow::Error) -> PyErr {
    let text = format!("{e:#}");
    let os = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>().is_some()
            || matches!(
                c.downcast_ref::<IngestError>(),
                Some(
                    IngestError::Io { .. }
                        | IngestError::Write { .. }
                        | IngestError::NotRegularFile { .. }
                        | IngestError::Interrupted { .. }
                )
            )
    });
    if os {
        PyOSError::new_err(text)
    } else {
        PyValueError::new_err(text)
    }
}

/// Parse `argv` (the flags after the subcommand) with the subcommand's clap arguments; a usage
/// error is its first line (what `stratus` prints), without clap's `error: `.
fn parse<A: clap::Args>(command: &str, argv: Vec<String>) -> PyResult<A> {
    #[derive(Parser)]
    struct Wrap<A: clap::Args> {
        #[command(flatten)]
        args: A,
    }
    let argv = std::iter::once(format!("stratus {command}")).chain(argv);
    match Wrap::<A>::try_parse_from(argv) {
        Ok(w) => Ok(w.args),
        Err(e) => {
            let text = e.to_string();
            let first = text.lines().next().unwrap_or("bad arguments");
            Err(PyValueError::new_err(
                first.strip_prefix("error: ").unwrap_or(first).to_string(),
            ))
        }
    }
}

/// The arrays of a dataset for Python: (group attributes as JSON, [(name, dims, dtype, shape,
/// little-endian bytes, attributes as JSON)]).
type Arrays<'py> = (
    String,
    Vec<(
        String,
        Vec<String>,
        &'static str,
        Vec<u64>,
        Bound<'py, PyBytes>,
        String,
    )>,
);

fn to_python(py: Python<'_>, d: dataset::Dataset) -> Arrays<'_> {
    let arrays = d
        .arrays
        .into_iter()
        .map(|a| {
            let attrs = serde_json::Value::Object(a.attributes).to_string();
            let bytes = PyBytes::new(py, &a.data);
            (a.name, a.dims, a.dtype, a.shape, bytes, attrs)
        })
        .collect();
    (serde_json::Value::Object(d.attributes).to_string(), arrays)
}

/// `stratus ingest FILES… [options] --out STORE`: a new Zarr store at `store` (the caller's
/// temporary folder), as the command line writes it. `argv`: the files and the options.
#[pyfunction]
fn ingest(py: Python<'_>, argv: Vec<String>, store: PathBuf) -> PyResult<()> {
    let mut argv = argv;
    argv.extend(["--out".to_string(), store.display().to_string()]);
    let a: cmd::ingest::Args = parse("ingest", argv)?;
    py.detach(|| ingest_store(&a)).map_err(to_py)
}

/// `src/cmd/ingest/store.rs`'s steps without its progress bar and summary line.
fn ingest_store(a: &cmd::ingest::Args) -> anyhow::Result<()> {
    use stratus_ingest::series::inputs::{series_steps, survey};
    let surveyed = a
        .files
        .iter()
        .map(|f| survey(f))
        .collect::<Result<Vec<_>, _>>()?;
    let steps = series_steps(&surveyed)?;
    let opts = a.ingest.options()?;
    stratus_ingest::zarr::write::create(&a.out, &steps, a.ingest.select(), &opts, &|_, _| {})?;
    Ok(())
}

/// Open a Zarr store, a PNG map's sidecar or a series sidecar as arrays.
#[pyfunction]
fn open(py: Python<'_>, path: PathBuf) -> PyResult<Arrays<'_>> {
    let d = py.detach(|| dataset::open(&path)).map_err(to_py)?;
    Ok(to_python(py, d))
}

/// `stratus render [flags]` (without `--out`): the picture as (RGBA bytes, width, height),
/// the frame the command would write to PNG, handed back by the renderer (no file).
#[pyfunction]
fn render(py: Python<'_>, argv: Vec<String>) -> PyResult<(Bound<'_, PyBytes>, u32, u32)> {
    let a: cmd::render::FrameArgs = parse("render", argv)?;
    let img = py
        .detach(|| {
            let scene = stratus::scene::Scene::open(&a.map);
            cmd::render::frame(&a, scene, |_| Ok(()))
        })
        .map_err(to_py)?;
    let (w, h) = img.dimensions();
    Ok((PyBytes::new(py, img.as_raw()), w, h))
}

/// `stratus score [flags] --json`: the report as its JSON text.
#[pyfunction]
fn score(py: Python<'_>, argv: Vec<String>) -> PyResult<String> {
    let a: cmd::score::Args = parse("score", argv)?;
    let r = py.detach(|| cmd::score::report(&a)).map_err(to_py)?;
    serde_json::to_string(&r).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The native half of the `stratus` package; `stratus/__init__.py` is the API.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(ingest, m)?)?;
    m.add_function(wrap_pyfunction!(open, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(score, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

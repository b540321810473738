"""Type stubs of the native module (python/src/lib.rs); the API is ``stratus/__init__.py``."""

from typing import List, Tuple

__version__: str

#: (group attributes as JSON, [(name, dims, dtype, shape, little-endian bytes, attributes as JSON)])
Arrays = Tuple[str, List[Tuple[str, List[str], str, List[int], bytes, str]]]

def ingest(argv: List[str], store: str) -> None:
    """``stratus ingest ARGV… --out STORE`` (a new Zarr store)."""

def open(path: str) -> Arrays:
    """A Zarr store, a map's sidecar or a series sidecar as arrays."""

def render(argv: List[str]) -> Tuple[bytes, int, int]:
    """``stratus render ARGV…`` without ``--out``: the frame as (RGBA bytes, width, height), no file."""

def score(argv: List[str]) -> str:
    """``stratus score ARGV…``: the report as JSON text."""

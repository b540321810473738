//! One Zarr v3 array as this store writes it: its `zarr.json` (regular chunk grid, the
//! "default" chunk key encoding `c/…` with `/`, the `bytes` codec little-endian then `gzip`),
//! and its chunks encoded and decoded. Only what the store needs of the specification
//! (<https://zarr-specs.readthedocs.io/en/latest/v3/core/index.html>): unsigned integers and
//! float64/int64 coordinates, no sharding, no transposition.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use serde_json::{json, Map, Value};

/// gzip level of every chunk: zlib's default, the size/time balance (docs/zarr.md).
pub const GZIP_LEVEL: u32 = 6;

/// The element types the store uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    U8,
    U16,
    I64,
    F64,
}

impl Dtype {
    pub fn name(self) -> &'static str {
        match self {
            Dtype::U8 => "uint8",
            Dtype::U16 => "uint16",
            Dtype::I64 => "int64",
            Dtype::F64 => "float64",
        }
    }

    pub fn size(self) -> usize {
        match self {
            Dtype::U8 => 1,
            Dtype::U16 => 2,
            Dtype::I64 | Dtype::F64 => 8,
        }
    }

    fn from_name(s: &str) -> Option<Dtype> {
        [Dtype::U8, Dtype::U16, Dtype::I64, Dtype::F64]
            .into_iter()
            .find(|d| d.name() == s)
    }
}

/// An array's metadata: what `zarr.json` says and what the reader checks.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayMeta {
    pub shape: Vec<u64>,
    pub chunks: Vec<u64>,
    pub dtype: Dtype,
    pub dims: Vec<String>,
    pub attributes: Map<String, Value>,
}

impl ArrayMeta {
    /// The array's `zarr.json`. Fill value 0: chunks are always written whole, so it only
    /// pads the edge chunks.
    pub fn to_json(&self) -> Value {
        let bytes = match self.dtype {
            Dtype::U8 => json!({"name": "bytes"}),
            _ => json!({"name": "bytes", "configuration": {"endian": "little"}}),
        };
        json!({
            "zarr_format": 3,
            "node_type": "array",
            "shape": self.shape,
            "data_type": self.dtype.name(),
            "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": self.chunks}},
            "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
            "fill_value": 0,
            "codecs": [bytes, {"name": "gzip", "configuration": {"level": GZIP_LEVEL}}],
            "attributes": self.attributes,
            "dimension_names": self.dims,
        })
    }

    /// Read back what [`to_json`](Self::to_json) writes; anything else is refused with what
    /// is wrong (this store's reader reads this store's arrays, not every Zarr array).
    pub fn from_json(v: &Value) -> Result<ArrayMeta, String> {
        let field = |k: &str| v.get(k).ok_or_else(|| format!("no {k:?}"));
        if field("zarr_format")? != &json!(3) || field("node_type")? != &json!("array") {
            return Err("not a Zarr v3 array".into());
        }
        let ints = |x: &Value, what: &str| -> Result<Vec<u64>, String> {
            x.as_array()
                .and_then(|a| a.iter().map(Value::as_u64).collect::<Option<Vec<_>>>())
                .ok_or_else(|| format!("{what} is not a list of whole numbers"))
        };
        let shape = ints(field("shape")?, "shape")?;
        let chunks = ints(
            v.pointer("/chunk_grid/configuration/chunk_shape")
                .ok_or("no regular chunk grid")?,
            "chunk_shape",
        )?;
        let dtype = field("data_type")?
            .as_str()
            .and_then(Dtype::from_name)
            .ok_or("data_type is not one this store writes")?;
        let dims = field("dimension_names")?
            .as_array()
            .and_then(|a| a.iter().map(|d| d.as_str().map(String::from)).collect())
            .ok_or("dimension_names is not a list of names")?;
        let want = ArrayMeta {
            shape: shape.clone(),
            chunks: chunks.clone(),
            dtype,
            dims,
            attributes: Map::new(),
        };
        // Key encoding and codecs must be exactly ours: the chunks are decoded that way.
        let ours = want.to_json();
        for k in ["chunk_key_encoding", "codecs", "fill_value"] {
            if v.get(k) != ours.get(k) {
                return Err(format!("{k} is not this store's"));
            }
        }
        if shape.len() != chunks.len()
            || want.dims.len() != shape.len()
            || chunks.contains(&0)
            || shape.iter().product::<u64>() > 1 << 40
        {
            return Err("shape, chunk_shape and dimension_names do not agree".into());
        }
        let attributes = v
            .get("attributes")
            .and_then(Value::as_object)
            .cloned()
            .unwrap_or_default();
        Ok(ArrayMeta { attributes, ..want })
    }

    /// Elements in one chunk.
    pub fn chunk_len(&self) -> usize {
        self.chunks.iter().product::<u64>() as usize
    }

    /// The file of the chunk at chunk-grid index `idx` under the array's folder `dir`.
    pub fn chunk_path(dir: &Path, idx: &[u64]) -> PathBuf {
        let mut p = dir.join("c");
        for i in idx {
            p.push(i.to_string());
        }
        p
    }
}

/// Elements (each held in a u64; float64 as its bits) as `dtype`'s little-endian bytes.
pub fn le_bytes(values: &[u64], dtype: Dtype) -> Vec<u8> {
    let mut raw = Vec::with_capacity(values.len() * dtype.size());
    for &v in values {
        match dtype {
            Dtype::U8 => raw.push(v as u8),
            Dtype::U16 => raw.extend_from_slice(&(v as u16).to_le_bytes()),
            Dtype::I64 | Dtype::F64 => raw.extend_from_slice(&v.to_le_bytes()),
        }
    }
    raw
}

/// A chunk's elements (already padded to the chunk's full size) as its stored bytes:
/// little-endian, gzip.
pub fn encode_chunk(values: &[u64], dtype: Dtype) -> Vec<u8> {
    let raw = le_bytes(values, dtype);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(GZIP_LEVEL));
    // Writing to a Vec cannot fail.
    let _ = gz.write_all(&raw);
    gz.finish().unwrap_or_default()
}

/// A chunk's stored bytes back to its `len` elements (each widened to u64; float64 as its
/// bits), or what is wrong with them.
pub fn decode_chunk(bytes: &[u8], dtype: Dtype, len: usize) -> Result<Vec<u64>, String> {
    let want = len * dtype.size();
    let mut raw = Vec::with_capacity(want);
    // One byte more than a whole chunk is read, so a chunk that inflates to more is caught
    // without inflating all of it.
    flate2::read::GzDecoder::new(bytes)
        .take(want as u64 + 1)
        .read_to_end(&mut raw)
        .map_err(|e| format!("not a gzip stream ({e})"))?;
    if raw.len() != want {
        return Err(format!(
            "inflates to {}{} bytes, not the chunk's {want}",
            raw.len().min(want),
            if raw.len() > want { "+" } else { "" }
        ));
    }
    Ok(match dtype {
        Dtype::U8 => raw.iter().map(|&b| b as u64).collect(),
        Dtype::U16 => raw
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as u64)
            .collect(),
        Dtype::I64 | Dtype::F64 => raw
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_and_metadata_round_trip() {
        let m = ArrayMeta {
            shape: vec![2, 3, 700, 600],
            chunks: vec![1, 1, 512, 512],
            dtype: Dtype::U16,
            dims: ["time", "layer", "lat", "lon"].map(String::from).to_vec(),
            attributes: Map::new(),
        };
        assert_eq!(ArrayMeta::from_json(&m.to_json()), Ok(m.clone()));
        let vals: Vec<u64> = (0..m.chunk_len() as u64).map(|v| v % 65536).collect();
        let enc = encode_chunk(&vals, Dtype::U16);
        assert_eq!(decode_chunk(&enc, Dtype::U16, vals.len()), Ok(vals.clone()));
        assert!(decode_chunk(&enc[..enc.len() / 2], Dtype::U16, vals.len()).is_err());
        assert!(decode_chunk(&enc, Dtype::U16, vals.len() - 1).is_err());
        assert!(decode_chunk(b"garbage", Dtype::U8, 4).is_err());
        assert_eq!(
            ArrayMeta::chunk_path(Path::new("s/v"), &[0, 2, 1, 0]),
            Path::new("s/v/c/0/2/1/0")
        );
        let mut other = m.to_json();
        other["codecs"] = json!([{"name": "bytes"}]);
        assert!(ArrayMeta::from_json(&other).is_err());
    }
}

//! Issue 13 (the forecast's vertical structure and cloud types), through the library, on the
//! real GFS files: the coverage PNG is unchanged byte for byte, multi-field messages decode.

use std::path::{Path, PathBuf};

use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::{LayerKind, Region};

fn shared(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared")
        .join(rel)
}

/// The real 2.5° sample, or `None` (with the reason printed) outside the checkout layout.
fn real(rel: &str) -> Option<PathBuf> {
    let p = shared(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent (run from the checkout)", p.display());
        None
    }
}

/// FNV-1a 64 over a PNG's chunks (type and data) except `tEXt`, which holds the pair's random
/// image id: equal hashes mean the same header, pixels and compressed stream.
fn png_hash_without_id(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |b: &[u8]| {
        for &x in b {
            h ^= x as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    let mut p = 8;
    while p + 12 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[p..p + 4].try_into().unwrap()) as usize;
        let ty = &bytes[p + 4..p + 8];
        if ty != b"tEXt" {
            eat(&bytes[p + 4..p + 8 + len]);
        }
        p += 12 + len;
    }
    h
}

fn coverage_png_hash(region: &str, size: (u32, u32), select: LevelSelect) -> u64 {
    let gfs = real("data/gfs/gfs.t12z.pgrbf120.2p5deg.grib2").unwrap();
    let fc = Forecast::open(&gfs, select).unwrap();
    let plan = Plan::new(
        &fc,
        &IngestOptions {
            region: Region::parse(region).unwrap(),
            width: size.0,
            height: size.1,
            rh_cr: LayerKind::DEFAULT_RH_CR,
            interp: Interp::Spline,
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("m.png");
    plan.write(&png, &|_| {}).unwrap();
    png_hash_without_id(&std::fs::read(&png).unwrap())
}

/// Hashes recorded with the ingest of main before issue 13 (commit a0cb52c): the structure,
/// type and wind images are added beside the coverage PNG, never into it.
#[test]
fn coverage_png_is_byte_identical_to_before() {
    if real("data/gfs/gfs.t12z.pgrbf120.2p5deg.grib2").is_none() {
        return;
    }
    let cases = [
        (
            "0,55,39,105",
            (260, 220),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
        (
            "30,65,-50,0",
            (400, 280),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
        ("0,55,39,105", (520, 440), LevelSelect::One(400.0)),
        (
            "-90,90,0,360",
            (288, 146),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        ),
    ];
    let got: Vec<u64> = cases
        .iter()
        .map(|(r, s, l)| coverage_png_hash(r, *s, *l))
        .collect();
    let want: [u64; 4] = [
        0x62d5_42ef_bcc3_f6b6,
        0xc92d_c573_8d52_476f,
        0xfea5_4c17_0bff_0cdb,
        0xbccb_a64e_8ebb_7658,
    ];
    assert_eq!(got, want);
}

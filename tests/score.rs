//! The Dice gate end to end on lavapipe with the real GFS sample, and proof that the score
//! falls when the render is wrong.

mod common;
use common::stratus;

use std::path::{Path, PathBuf};

use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus::score;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::forecast::{Forecast, LevelSelect};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::region::Region;
use stratus_ingest::spline::Interp;

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data-samples")
        .join(rel)
}

const GFS: &str = "gfs/gfs.t12z.pgrbf120.2p5deg.grib2";
/// The CI gate (issue 13): DSC ≥ 0.95 at every preset from fast up, East Asia and the North
/// Atlantic, 400 hPa and all layers, scored in the default 4×4 blocks (a cumulus coverage is
/// an area). Measured here (docs/score.md): 0.978–0.990; a wrong render scores below 0.75
/// (test below).
const GATE: &str = "0.95";
const EAST_ASIA: &str = "0,55,39,105";
const NORTH_ATLANTIC: &str = "30,70,-60,30";

fn gate(region: &str, extra: &[&str], preset: &str) {
    let g = sample(GFS);
    let mut args = vec![
        "score",
        "--grib",
        g.to_str().unwrap(),
        "--region",
        region,
        "--size",
        "520x440",
        "--preset",
        preset,
        "--min-dice",
        GATE,
    ];
    args.extend_from_slice(extra);
    let o = stratus(&args);
    let out = String::from_utf8_lossy(&o.stdout);
    println!("{out}");
    assert_eq!(
        o.status.code(),
        Some(0),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("total"), "{out}");
}

#[test]
fn gate_400hpa_every_preset_both_regions() {
    for region in [EAST_ASIA, NORTH_ATLANTIC] {
        for p in ["fast", "balanced", "high"] {
            gate(region, &["--level", "400", "--rh-cr", "0.65"], p);
        }
    }
}

#[test]
fn gate_all_layers_every_preset_both_regions() {
    for region in [EAST_ASIA, NORTH_ATLANTIC] {
        for p in ["fast", "balanced", "high"] {
            gate(region, &[], p);
        }
    }
}

fn east_asia(level: Option<f64>) -> CloudMap {
    let bytes = std::fs::read(sample(GFS)).unwrap();
    let sel = match level {
        Some(l) => LevelSelect::One(l),
        None => LevelSelect::AllBelow(100.0),
    };
    let fc = Forecast::from_bytes(Path::new("gfs"), &bytes, sel).unwrap();
    let opts = IngestOptions {
        region: Region::parse("0,55,39,105").unwrap(),
        width: 520,
        height: 440,
        rh_cr: [0.80, 0.65, 0.65],
        interp: Interp::Spline,
    };
    Plan::new(&fc, &opts).unwrap().build()
}

/// The map moved east by `dx` pixels (wrapping), or flipped north–south.
fn altered(map: &CloudMap, dx: usize, flip: bool) -> CloudMap {
    let (w, h) = (map.width(), map.height());
    let mut m = map.clone();
    for j in 0..h {
        for i in 0..w {
            let sj = if flip { h - 1 - j } else { j };
            m.texels[j * w + (i + dx) % w] = map.texels[sj * w + i];
        }
    }
    m
}

#[test]
fn wrong_renders_score_far_lower() {
    let map = east_asia(Some(400.0));
    let mut r = Renderer::new(Gpu::new(None).unwrap(), &map);
    let s = Settings::new(Preset::Fast, chrono::Utc::now());
    let (w, h) = (map.meta.width, map.meta.height);
    let dice_against = |r: &mut Renderer, rendered: &CloudMap, truth: &CloudMap| {
        r.set_map(rendered);
        let out = r.render(&View::TopDown, w, h, &s).unwrap();
        let size = (w, h);
        let (opacity, _) = score::block_mean(&out.alpha(), size, score::BLOCK);
        let coverage = score::map_channel(truth, 3, w, h);
        let (coverage, _) = score::block_mean(&coverage, size, score::BLOCK);
        let rm = score::mask(&opacity, score::RENDER_THRESHOLD);
        score::compare(&rm, &score::mask(&coverage, score::MAP_THRESHOLD)).dice
    };
    let truth = dice_against(&mut r, &map, &map);
    let shifted = dice_against(&mut r, &altered(&map, w as usize / 10, false), &map);
    let flipped = dice_against(&mut r, &altered(&map, 0, true), &map);
    println!("true {truth:.4}, shifted a tenth {shifted:.4}, flipped {flipped:.4}");
    assert!(truth > 0.93, "{truth}");
    assert!(shifted < truth - 0.2, "shifted {shifted} vs {truth}");
    assert!(flipped < truth - 0.2, "flipped {flipped} vs {truth}");
}

#[test]
fn empty_masks_and_the_gate_failing() {
    // An all-zero real field: both masks empty → DSC 1 with a note, not a division by zero.
    let z = sample("gfs/gfs.t18z.pgrb2.0p25.f186-RH.grib2");
    let o = stratus(&[
        "score",
        "--grib",
        z.to_str().unwrap(),
        "--region",
        "0,55,39,105",
        "--size",
        "200x160",
        "--level",
        "0.7",
        "--json",
        "--preset",
        "fast",
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["total"]["dice"], 1.0);
    assert!(v["total"]["note"]
        .as_str()
        .unwrap()
        .contains("both masks are empty"));
    // An impossible gate exits 1 (not 2: the run worked, the score is too low).
    let g = sample(GFS);
    let dir = tempfile::tempdir().unwrap();
    let diff = dir.path().join("d.png");
    let o = stratus(&[
        "score",
        "--grib",
        g.to_str().unwrap(),
        "--region",
        "0,55,39,105",
        "--size",
        "200x160",
        "--level",
        "400",
        "--min-dice",
        "0.99999",
        "--preset",
        "fast",
        "--diff",
        diff.to_str().unwrap(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("below --min-dice"));
    let img = image::open(&diff).unwrap();
    // One diff pixel per block.
    assert_eq!((img.width(), img.height()), (50, 40));
}

#[test]
fn one_empty_mask_scores_zero() {
    let a = vec![false; 100];
    let mut b = vec![false; 100];
    b[3] = true;
    let s = score::compare(&a, &b);
    assert_eq!(s.dice, 0.0);
    assert!(s.dice.is_finite() && s.iou.is_finite());
}

// ---------------------------------------------------------------------------------------------
// The gate beyond its own cases (issue 30): maps the fixed cases never use, drawn at test time.

/// SplitMix64: a few lines, reproducible from the printed seed on every platform.
struct Draw(u64);

impl Draw {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in lo..hi.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[(self.next() % v.len() as u64) as usize]
    }
}

/// One drawn case: the `score` arguments after `--grib FILE`.
#[derive(Debug)]
struct Case {
    file: &'static str,
    region: String,
    level: Option<u32>,
    rh_cr: f64,
    preset: &'static str,
}

impl Case {
    fn draw(d: &mut Draw) -> Case {
        // The real GFS files (the 0.25° Poland cut covers only 48–56°N 13–25°E).
        const GLOBAL: [&str; 3] = [
            "gfs/gfs.t12z.pgrbf120.2p5deg.grib2",
            "gfs-series/gfs.t18z.pgrb2.2p50.f000",
            "gfs-series/gfs.t18z.pgrb2.2p50.f006",
        ];
        const POLAND: [&str; 3] = [
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f000",
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f006",
            "gfs-series-poland/gfs.20200804.t12z.pgrb2.0p25.f012",
        ];
        let (file, region) = if d.next().is_multiple_of(5) {
            (*d.pick(&POLAND), "48,56,13,25".to_string())
        } else {
            // A box 25–50° high and 30–70° wide anywhere between 65°S and 75°N.
            let h = d.range(25.0, 50.0).round();
            let w = d.range(30.0, 70.0).round();
            let s = d.range(-65.0, 75.0 - h).round();
            let west = d.range(-180.0, 180.0 - w).round();
            (
                *d.pick(&GLOBAL),
                format!("{s},{},{west},{}", s + h, west + w),
            )
        };
        let level = *d.pick(&[Some(850), Some(700), Some(500), Some(400), Some(300), None]);
        let rh_cr = *d.pick(&[0.65, 0.7, 0.75, 0.8, 0.85]);
        let preset = *d.pick(&["fast", "balanced", "high"]);
        Case {
            file,
            region,
            level,
            rh_cr,
            preset,
        }
    }

    /// The total DSC `score` gives it, and the share of the map's blocks that are cloud.
    fn dice(&self) -> (f64, f64) {
        let g = sample(self.file);
        let level = self.level.map(|l| l.to_string());
        let rh = self.rh_cr.to_string();
        let mut args = vec![
            "score",
            "--grib",
            g.to_str().unwrap(),
            "--region",
            &self.region,
            "--size",
            "520x440",
            "--preset",
            self.preset,
            "--rh-cr",
            &rh,
            "--json",
        ];
        if let Some(l) = &level {
            args.extend(["--level", l]);
        }
        let o = stratus(&args);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{self:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let t = &v["total"];
        let share = t["map_px"].as_f64().unwrap() / t["total_px"].as_f64().unwrap();
        (t["dice"].as_f64().unwrap(), share)
    }
}

/// Least share of a drawn map's blocks that must be cloud for its Dice to say anything about
/// the cloud's shape: at 1 % (143 blocks of the 130×110 the score makes) one block is 0.35 % of
/// the Dice and the gate allows about 14 wrong; a map with 16 cloudy blocks scored 0.68 on six
/// (docs/footprint.md, "A draw CI made"). Such a draw is printed and another drawn.
const LEAST_CLOUD: f64 = 0.01;

/// Draw `n` cases from `seed` and hold each to the gate; the seed and every score are printed.
fn drawn_cases_reach_the_gate(seed: u64, n: usize) {
    println!("STRATUS_SCORE_SEED={seed}");
    let mut d = Draw(seed);
    let mut low = Vec::new();
    let (mut scored, mut drawn) = (0, 0);
    while scored < n {
        drawn += 1;
        assert!(
            drawn <= 4 * n,
            "seed {seed}: {drawn} draws for {n} with cloud"
        );
        let c = Case::draw(&mut d);
        let (dice, share) = c.dice();
        if share < LEAST_CLOUD {
            println!(
                "skipped: {:.2} % of the blocks cloudy  {c:?}",
                share * 100.0
            );
            continue;
        }
        scored += 1;
        println!("DSC {dice:.4}  {c:?}");
        if dice < GATE.parse::<f64>().unwrap() {
            low.push(format!("{dice:.4} {c:?}"));
        }
    }
    assert!(
        low.is_empty(),
        "seed {seed}: below the gate {GATE}:\n{}",
        low.join("\n")
    );
}

fn cases_wanted() -> usize {
    std::env::var("STRATUS_SCORE_CASES")
        .ok()
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(3)
}

/// The three cases CI drew on 2026-11-26 (seed 1795714834): the second, a 700 hPa analysis
/// over the Coral Sea at `fast`, scored 0.9463 and turned CI red. Shallow convective columns
/// drawn as towers (now drawn as cumulus, render::structure::MIN_TOWER_M) and `fast`'s edges
/// drawn without the detail's mean erosion (cloud.wgsl `carve`) were why; it scores 0.9850 now.
/// Kept beside the random draws so that a draw that once failed is drawn again in every run.
/// And the three a test run drew on 2026-11-28 (seed 1795825779): the first, 500 hPa over
/// Poland on the 0.25° file at `high`, scored 0.9444: its 2 km map pixels drew the
/// cumulonimbus' towers, not their mean (cloud.wgsl `TOWER_MEAN_FROM_M`); 0.9766 now.
#[test]
fn gate_holds_on_the_cases_ci_drew() {
    drawn_cases_reach_the_gate(1_795_714_834, 3);
    drawn_cases_reach_the_gate(1_795_825_779, 3);
}

/// Seeded random cases beside the fixed ones: a file among the real GFS samples, a region, one
/// level (850–300 hPa) or all layers, an rh_cr and a preset; each must reach the gate. The seed
/// is printed (STRATUS_SCORE_SEED=N repeats a run; STRATUS_SCORE_CASES=N draws N, default 3).
///
///
/// Measured on 40 draws of seeds 777, 2026, 30 and 4242 after the cumulonimbus' mean
/// (docs/footprint.md, "A draw CI made, and the cumulonimbus' mean"): every one ≥ 0.956.
#[test]
fn gate_holds_on_random_maps() {
    let seed = std::env::var("STRATUS_SCORE_SEED")
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        });
    drawn_cases_reach_the_gate(seed, cases_wanted());
}

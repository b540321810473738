//! The embedded samples and the fixed views over them that `demo`, `bench` and the tests share:
//! where each sample file is, how it is ingested, and which cameras look at it.

use std::path::{Path, PathBuf};

use chrono::{DateTime, TimeZone, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::meta::LayerKind;
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::region::Region;
use stratus_ingest::spline::Interp;
use stratus_ingest::IngestError;

use crate::render::{Camera, View};

/// A fixed view with its time of day (`None`: the map's valid time).
#[derive(Clone, Copy, Debug)]
pub struct Scene {
    pub name: &'static str,
    pub view: View,
    pub time: Option<DateTime<Utc>>,
}

/// A GRIB2 file in `data-samples/` and how the demo and bench ingest and view it.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Path relative to the workspace root.
    pub file: &'static str,
    pub region: Region,
    pub size: (u32, u32),
    /// The views over it.
    pub scenes: Vec<Scene>,
    /// The ones `stratus demo` renders, by name.
    pub demo_views: Vec<&'static str>,
}

/// The region both samples cover: 30–60°N, 40°W–0°, the North Atlantic west of Europe.
const NORTH_ATLANTIC: Region = Region {
    south: 30.0,
    north: 60.0,
    west: -40.0,
    east: 0.0,
};

/// The straight-down view the score compares with the map.
const TOP_DOWN: Scene = Scene {
    name: "top-down",
    view: View::TopDown,
    time: None,
};

fn utc(y: i32, mo: u32, d: u32, h: u32, mi: u32) -> Option<DateTime<Utc>> {
    Utc.with_ymd_and_hms(y, mo, d, h, mi, 0).single()
}

/// The synthetic sample (a cold front over the North Atlantic with invented values): what the
/// bench and the tests that need a known field use.
pub fn synthetic() -> Sample {
    let dusk = utc(2024, 6, 1, 20, 45);
    Sample {
        file: "data-samples/synthetic-gfs-rh.grib2",
        region: NORTH_ATLANTIC,
        size: (800, 600),
        scenes: vec![
            Scene {
                name: "above-noon",
                view: View::Perspective(Camera::new(45.5, -22.0, 12_000.0, 45.0, -12.0)),
                time: None,
            },
            Scene {
                name: "above-dusk",
                view: View::Perspective(Camera::new(45.5, -22.0, 12_000.0, 45.0, -12.0)),
                time: dusk,
            },
            Scene {
                name: "inside-layer",
                view: View::Perspective(Camera::new(47.0, -17.0, 4_500.0, 60.0, 0.0)),
                time: None,
            },
            Scene {
                name: "horizon-ground",
                view: View::Perspective(Camera::new(36.0, -28.6, 50.0, 45.0, 10.0)),
                time: None,
            },
            Scene {
                name: "horizon-dusk",
                view: View::Perspective(Camera::new(36.0, -28.6, 50.0, 45.0, 10.0)),
                time: dusk,
            },
            TOP_DOWN,
        ],
        demo_views: vec!["above-noon", "above-dusk", "inside-layer", "horizon-ground"],
    }
}

/// The real sample: a cut of NCEP's GFS 2.5° forecast for 2011-01-15 12 UTC (+120 h), over the
/// same region, where a textbook cold front runs south-west to north-east with low cloud along
/// and behind it, a dry slot to the north-west and clear air to the south-east.
pub fn gfs() -> Sample {
    let above = View::Perspective(Camera::new(42.5, -26.0, 16_000.0, 60.0, -12.0));
    Sample {
        file: "data-samples/gfs-2011011012-f120-2p5.grib2",
        region: NORTH_ATLANTIC,
        size: (800, 600),
        scenes: vec![
            // Over the dry slot, looking across the front's deck (Sun about 21° up).
            Scene {
                name: "above-noon",
                view: above,
                time: None,
            },
            // The same at sunset there (Sun about 3° up).
            Scene {
                name: "above-dusk",
                view: above,
                time: utc(2011, 1, 15, 18, 10),
            },
            // In the middle layer's band, between the low deck and the high overcast.
            Scene {
                name: "inside-layer",
                view: View::Perspective(Camera::new(37.8, -20.9, 5_000.0, 340.0, 0.0)),
                time: None,
            },
            // From the sea in the dry slot, toward the front.
            Scene {
                name: "horizon-ground",
                view: View::Perspective(Camera::new(44.2, -23.6, 50.0, 150.0, 15.0)),
                time: None,
            },
            TOP_DOWN,
            // The demo's views (issue 30: the weather, not clear sea and sky). Above the cold
            // front's north-western edge (41°N 26°W: altocumulus thickening southward into
            // nimbostratus under cirrus), looking south over its deck.
            Scene {
                name: "front-above",
                view: View::Perspective(Camera::new(41.5, -26.2, 15_000.0, 170.0, -20.0)),
                time: None,
            },
            // The same edge from the sea just behind it: broken altocumulus overhead merging
            // into the front's deck to the south.
            Scene {
                name: "front-below",
                view: View::Perspective(Camera::new(41.6, -26.0, 50.0, 180.0, 20.0)),
                time: None,
            },
            // At 1 km at the south-western edge of the cumulonimbus cluster (49–51.5°N,
            // 26–22°W), looking at one tower and its anvil.
            Scene {
                name: "cumulonimbus",
                view: View::Perspective(Camera::new(49.4, -25.5, 1_000.0, 62.0, 8.0)),
                time: None,
            },
            // Over the broken cumulus behind the front (53°N 33°W: low 0.75, tops 2.4 km).
            Scene {
                name: "broken-field",
                view: View::Perspective(Camera::new(53.0, -33.0, 4_000.0, 90.0, -30.0)),
                time: None,
            },
        ],
        demo_views: vec!["front-above", "front-below", "cumulonimbus", "broken-field"],
    }
}

/// The real sample again, over the Himalaya and the Tibetan Plateau (20–40°N, 75–100°E): the
/// bench's scene with terrain (the file's orography, 4–6 km under the plateau's cloud).
pub fn terrain() -> Sample {
    Sample {
        file: "data-samples/gfs-2011011012-f120-2p5.grib2",
        region: Region {
            south: 20.0,
            north: 40.0,
            west: 75.0,
            east: 100.0,
        },
        size: (500, 400),
        scenes: vec![
            // 400 m over the plateau's southern edge (ground 5.6 km), toward the overcast over
            // its middle, near local noon.
            Scene {
                name: "over-terrain",
                view: View::Perspective(Camera::new(30.5, 86.0, 6_000.0, 0.0, 8.0)),
                time: utc(2011, 1, 15, 6, 0),
            },
        ],
        demo_views: vec![],
    }
}

/// The sample the demo shows: real weather.
pub fn demo() -> Sample {
    gfs()
}

impl Sample {
    /// The file, found from the current directory or the workspace this binary was built in.
    pub fn path(&self) -> PathBuf {
        let here = Path::new(self.file);
        if here.exists() {
            return here.to_path_buf();
        }
        Path::new(env!("CARGO_MANIFEST_DIR")).join(self.file)
    }

    /// How it is ingested: every level folded into three layers with the default rh_cr.
    pub fn options(&self) -> IngestOptions {
        IngestOptions {
            region: self.region,
            width: self.size.0,
            height: self.size.1,
            rh_cr: LayerKind::ALL.map(LayerKind::default_rh_cr),
            interp: Interp::Spline,
        }
    }

    /// Read `file` (this sample's or another forecast) and prepare the resampling.
    pub fn plan(&self, file: &Path) -> Result<Plan, IngestError> {
        let fc = Forecast::open(file, LevelSelect::AllBelow(DEFAULT_TOP_HPA))?;
        Plan::new(&fc, &self.options())
    }

    /// The sample's CloudMap, in memory.
    pub fn map(&self) -> Result<CloudMap, IngestError> {
        Ok(self.plan(&self.path())?.build())
    }

    /// The scene called `name`.
    pub fn scene(&self, name: &str) -> Option<Scene> {
        self.scenes.iter().copied().find(|s| s.name == name)
    }

    /// The scenes called `names`, in that order (unknown names are left out).
    pub fn scenes_named(&self, names: &[&str]) -> Vec<Scene> {
        names.iter().filter_map(|n| self.scene(n)).collect()
    }
}

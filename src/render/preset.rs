//! Quality presets: how finely rays are marched and which shortcuts are on (DESIGN §4, §4b).
//!
//! `reference` defines "accurate": fixed small steps, no early exit, no skipping or culling,
//! a long light march. The other presets trade accuracy for speed; `stratus bench` measures
//! by how much.

use serde::{Deserialize, Serialize};

/// A named quality level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    Fast,
    Balanced,
    High,
    Reference,
}

impl std::str::FromStr for Preset {
    type Err = String;

    fn from_str(s: &str) -> Result<Preset, String> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown preset \"{s}\" (fast, balanced, high, reference)"))
    }
}

impl Preset {
    pub const ALL: [Preset; 4] = [
        Preset::Fast,
        Preset::Balanced,
        Preset::High,
        Preset::Reference,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Preset::Fast => "fast",
            Preset::Balanced => "balanced",
            Preset::High => "high",
            Preset::Reference => "reference",
        }
    }

    /// The march parameters this preset stands for.
    pub fn params(self) -> MarchParams {
        let on = Shortcuts::all();
        match self {
            Preset::Fast => MarchParams {
                step_min_m: 100.0,
                step_growth: 0.02,
                step_max_m: 3000.0,
                max_steps: 200,
                light_steps: 2,
                light_reach_m: 800.0,
                early_exit: 0.05,
                detail: false,
                column_light: true,
                terrain: true,
                aerial: true,
                subset: 4,
                graze: false,
                graze_apart: 0.04,
                graze_column: 1.0,
                graze_from: 0.5,
                shortcuts: on,
            },
            Preset::Balanced => MarchParams {
                step_min_m: 50.0,
                step_growth: 0.01,
                step_max_m: 1500.0,
                max_steps: 400,
                light_steps: 3,
                light_reach_m: 800.0,
                early_exit: 0.04,
                detail: true,
                column_light: true,
                terrain: true,
                aerial: true,
                subset: 4,
                graze: true,
                graze_apart: 0.015,
                graze_column: 0.0,
                graze_from: 0.5,
                shortcuts: on,
            },
            Preset::High => MarchParams {
                step_min_m: 25.0,
                step_growth: 0.005,
                step_max_m: 800.0,
                max_steps: 800,
                light_steps: 4,
                light_reach_m: 800.0,
                early_exit: 0.01,
                detail: true,
                column_light: true,
                terrain: true,
                aerial: true,
                subset: 2,
                graze: true,
                graze_apart: 0.04,
                graze_column: 1.0,
                graze_from: 0.5,
                shortcuts: on,
            },
            Preset::Reference => MarchParams {
                step_min_m: 10.0,
                step_growth: 0.0,
                step_max_m: 10.0,
                max_steps: 40_000,
                light_steps: 6,
                light_reach_m: 800.0,
                early_exit: 0.0,
                detail: true,
                column_light: true,
                terrain: true,
                aerial: true,
                subset: 1,
                graze: true,
                graze_apart: 0.04,
                graze_column: 1.0,
                // The standard the others are scored against marches every ray from the
                // camera, as it takes no other shortcut.
                graze_from: 0.0,
                shortcuts: Shortcuts {
                    early_exit: false,
                    variable_step: false,
                    region_cull: false,
                    empty_skip: false,
                    light_lod: false,
                    jitter: false,
                    clear_stride: false,
                    feature_reach: false,
                },
            },
        }
    }
}

/// The optimisations, each switchable alone to measure what it buys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shortcuts {
    pub early_exit: bool,
    pub variable_step: bool,
    pub region_cull: bool,
    pub empty_skip: bool,
    pub light_lod: bool,
    pub jitter: bool,
    /// Double, then quadruple, the step in clear air; on meeting cloud back up and go on at
    /// the normal step (Nubis' cheap-then-fine sampling, DESIGN §4b).
    pub clear_stride: bool,
    /// The march compiles in the cumulus cells', towers' and streaks' code only where a
    /// column holding them is within the frame's reach, not anywhere on the map (render::reach;
    /// the same pictures, less code per step on a CPU driver).
    #[serde(default = "on")]
    pub feature_reach: bool,
}

fn on() -> bool {
    true
}

fn graze_apart() -> f32 {
    0.04
}

fn graze_column() -> f32 {
    1.0
}

fn graze_from() -> f32 {
    0.5
}

impl Shortcuts {
    pub fn all() -> Shortcuts {
        Shortcuts {
            early_exit: true,
            variable_step: true,
            region_cull: true,
            empty_skip: true,
            light_lod: true,
            jitter: true,
            clear_stride: true,
            feature_reach: true,
        }
    }
}

/// What the march shader is told.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarchParams {
    /// Step length at the camera (m).
    pub step_min_m: f32,
    /// Step growth per metre of distance (variable step: dt = min + growth·t).
    pub step_growth: f32,
    pub step_max_m: f32,
    pub max_steps: u32,
    pub light_steps: u32,
    /// Total length of the light march toward the Sun (m), the same for every preset so they
    /// differ in sample count only; the steps are equal but the last, 6× longer (coursework A.2).
    pub light_reach_m: f32,
    /// Stop once transmittance falls below this.
    pub early_exit: f32,
    /// Detail (erosion) noise on.
    pub detail: bool,
    /// Full-column light and cloud shadows (render::shadow): the light beyond the short light
    /// march, the sky through the column above, the ground in the clouds' shadows.
    pub column_light: bool,
    /// The forecast's terrain marched as a height field (else the ground is a sea-level sphere).
    pub terrain: bool,
    /// The clear air's light and extinction in front of ground and cloud (the atmosphere's
    /// aerial-perspective table); else only the visibility's haze.
    pub aerial: bool,
    /// Side of the reprojection's subset cell (px): a reprojected frame (the window, `flight`)
    /// marches one pixel of each `subset`×`subset` cell and reprojects the rest
    /// (render::reproject); 1 marches every pixel. A power of two, at most 8.
    pub subset: u32,
    /// A pixel whose ray grazes the layers (between the sea's limb and just above the
    /// horizontal, where a far deck's top or base crosses a row as a line thinner than a pixel)
    /// takes four more rays down its height where its one ray's picture stands out from its
    /// neighbours' on screen (`graze_apart`, `graze_column`). On for `balanced`, `high` and
    /// `reference`; off for `fast`, for its cost in the views with the horizon in frame
    /// (docs/footprint.md has it, session by session). Frames that march a subset of the
    /// pixels (reprojection) at the target's size go without (docs/footprint.md, "Grazing rays
    /// where the picture asks"); a march enlarged into its target (the window's render scale)
    /// takes them at every preset (render::frame::build).
    #[serde(default)]
    pub graze: bool,
    /// How far a grazing pixel's picture must stand out on screen (after the tone curve, 0..1)
    /// to take the extra rays: from a neighbour in its row, or down its column from its two
    /// neighbours' mean (the picture's bend there: a line thinner than the pixel stands out
    /// from both sides, a smooth gradient does not).
    #[serde(default = "graze_apart")]
    pub graze_apart: f32,
    /// How much a column neighbour's own distance counts beside the column's bend: 0, the bend
    /// alone (`balanced`, at 0.015); 1, either neighbour too, the test before the bend (`high`
    /// and `reference`, at 0.04: the bend at 0.015 made `high` above the clouds no faster than
    /// the code before issue 30; docs/footprint.md, "Grazing rays where the picture bends").
    #[serde(default = "graze_column")]
    pub graze_column: f32,
    /// Where a grazing pixel's extra rays start: this share of the distance at which its centre
    /// ray first read the cloud's noise, before which the map alone left its air clear (below,
    /// above or between the drawn layers, outside their cover). Along the horizon under an
    /// overcast that is most of their way (docs/footprint.md, "The extra rays past the clear
    /// air"). 0 marches them from the camera (`reference`); above 1 they would start past cloud
    /// the centre ray met.
    #[serde(default = "graze_from")]
    pub graze_from: f32,
    pub shortcuts: Shortcuts,
}

impl MarchParams {
    /// Parameters with the switched-off shortcuts made inert.
    pub fn effective(&self) -> MarchParams {
        let mut p = *self;
        if !p.shortcuts.early_exit {
            p.early_exit = 0.0;
        }
        if !p.shortcuts.variable_step {
            p.step_growth = 0.0;
            p.step_max_m = p.step_min_m;
            // The same distance needs more steps at the near step length.
            p.max_steps = p.max_steps.saturating_mul(8).min(40_000);
        }
        p
    }
}

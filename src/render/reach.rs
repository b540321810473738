//! Which of the map's genus features a perspective frame can reach. The march's pipeline
//! variant compiles in the cumulus cells', cumulonimbus towers' and cirrus streaks' code only
//! where the map has them (render::pipeline); this narrows "the map" to the columns the
//! frame's rays and their light samples can meet. On a SIMD CPU driver every lane runs every
//! branch compiled in, taken or not: a view with no cumulus in range paid for the cells' code
//! on every step (docs/performance.md, "Features within the frame's reach"). The pictures are
//! the same: a feature's code only runs where the sample's column holds that genus.
//!
//! The test is conservative. The columns holding a feature are gathered in blocks of texels;
//! a block is reached unless its vertical segment through the cloud shell, widened by the
//! block's radius and the light march's length, lies wholly outside one side of the frustum,
//! or farther from the camera than any ray can go before it meets the ground or leaves the
//! shell.

use glam::DVec3;
use stratus_ingest::meta::StructureGrid;

use super::camera::{ecef, Camera, EARTH_R};
use super::frame::flags;

/// The flags this module can leave out of a frame's march.
pub const REACHABLE: u32 = flags::CELLS | flags::TOWERS | flags::STREAKS;

/// Most blocks a map's features are gathered into: the per-frame test stays well under a
/// millisecond on a map's own 0.25° lattice.
const MAX_BLOCKS: usize = 4096;

/// Metres of arc a degree of latitude spans.
const M_PER_DEG: f64 = EARTH_R * std::f64::consts::PI / 180.0;

/// The lowest the ground can be (m below sea level): a ray ends there at the latest.
const LOWEST_GROUND_M: f64 = 1000.0;

/// The columns of a map that hold each feature, in blocks.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FeatureColumns {
    /// Unit ECEF direction of a block's centre, and the [`REACHABLE`] flags its texels hold.
    blocks: Vec<(DVec3, u32)>,
    /// How far from a block's centre its features can be drawn (m): its texels' span, and the
    /// one texel more that the genus look-up's dither reaches (cloud.wgsl `column_density`).
    radius_m: f64,
}

impl FeatureColumns {
    /// The blocks of `bits` (one entry of [`REACHABLE`] flags a texel of `grid`, row-major).
    pub fn new(grid: &StructureGrid, bits: &[u32]) -> FeatureColumns {
        let (w, h) = (grid.width as usize, grid.height as usize);
        if bits.len() != w * h {
            // Not this lattice's (structure.rs makes them so): every feature everywhere.
            return FeatureColumns {
                blocks: vec![(DVec3::Z, REACHABLE)],
                radius_m: f64::INFINITY,
            };
        }
        let side = ((w * h) as f64 / MAX_BLOCKS as f64).sqrt().ceil().max(1.0) as usize;
        let mut blocks = Vec::new();
        for by in (0..h).step_by(side) {
            for bx in (0..w).step_by(side) {
                let rows = by..(by + side).min(h);
                let held = rows
                    .flat_map(|y| bits[y * w + bx..y * w + (bx + side).min(w)].iter())
                    .fold(0, |acc, &b| acc | b);
                if held != 0 {
                    // The block's centre in lattice coordinates (it may be cut at an edge: its
                    // radius below is a whole block's, which covers it).
                    let (cx, cy) = (
                        bx as f64 + 0.5 * (side - 1) as f64,
                        by as f64 + 0.5 * (side - 1) as f64,
                    );
                    let (lat, lon) = (grid.north - cy * grid.dlat, grid.west + cx * grid.dlon);
                    blocks.push((ecef(lat, lon, 0.0).normalize(), held & REACHABLE));
                }
            }
        }
        // A degree of longitude is widest at the equator: the radius holds at any latitude.
        let texel_m = (grid.dlat * M_PER_DEG).hypot(grid.dlon * M_PER_DEG);
        FeatureColumns {
            blocks,
            radius_m: (0.5 * (side - 1) as f64 + 1.0) * texel_m,
        }
    }

    /// Both maps' columns (a blend of two forecast steps may draw either's genus).
    pub fn union(&self, other: &FeatureColumns) -> FeatureColumns {
        FeatureColumns {
            blocks: self.blocks.iter().chain(&other.blocks).copied().collect(),
            radius_m: self.radius_m.max(other.radius_m),
        }
    }

    /// The [`REACHABLE`] flags held by no block that the frame can reach.
    pub fn unreached(&self, view: &Frustum) -> u32 {
        let mut reached = 0;
        for &(dir, held) in &self.blocks {
            if held & !reached != 0 && view.reaches(dir, self.radius_m) {
                reached |= held;
                if reached == REACHABLE {
                    break;
                }
            }
        }
        REACHABLE & !reached
    }
}

/// What a perspective frame's rays can meet: its frustum, the cloud shell, and how far its
/// light samples go from a view ray.
pub struct Frustum {
    position: DVec3,
    /// Outward unit normals of the four sides (through the camera).
    sides: [DVec3; 4],
    /// The farthest a ray can reach inside the shell before the ground (m).
    range_m: f64,
    /// The shell's radii from the Earth's centre (m).
    shell: (f64, f64),
    /// Added to every distance test (m): the light march, a kilometre's slack.
    margin_m: f64,
}

impl Frustum {
    /// `aspect`: the march's width over its height; `shell`: its base and top (m);
    /// `light_reach_m`: how far a light sample goes toward the Sun.
    pub fn new(cam: &Camera, aspect: f64, shell: (f64, f64), light_reach_m: f64) -> Frustum {
        let b = cam.basis();
        // Rays leave through the edge pixels' far sides, with the jitter and split rays inside
        // their pixels: a few per cent of the field of view is more than a pixel's width.
        let ty = (cam.fov_deg.to_radians() * 0.5).tan() * 1.05;
        let tx = ty * aspect;
        let side = |axis: DVec3, t: f64| (axis - b.forward * t).normalize();
        let sides = [
            side(b.right, tx),
            side(-b.right, tx),
            side(b.view_up, ty),
            side(-b.view_up, ty),
        ];
        let r = |alt: f64| EARTH_R + alt;
        let ground = r(-LOWEST_GROUND_M);
        let chord = |radius: f64| (radius * radius - ground * ground).max(0.0).sqrt();
        Frustum {
            position: b.position,
            sides,
            range_m: chord(r(cam.alt_m.max(0.0))) + chord(r(shell.1)),
            shell: (r(shell.0), r(shell.1)),
            margin_m: light_reach_m.max(0.0) + 1000.0,
        }
    }

    /// Whether a column `radius_m` wide around ground direction `dir` can be met.
    fn reaches(&self, dir: DVec3, radius_m: f64) -> bool {
        // The radius is measured at sea level; at the shell's top the columns are farther apart.
        let m = radius_m * self.shell.1 / EARTH_R + self.margin_m;
        let a = dir * self.shell.0 - self.position;
        let b = dir * self.shell.1 - self.position;
        if self.sides.iter().any(|n| a.dot(*n) > m && b.dot(*n) > m) {
            return false;
        }
        distance_to_segment(a, b) <= self.range_m + m
    }
}

/// Distance from the origin to the segment a–b.
fn distance_to_segment(a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        (-a.dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1° lattice of 41×41 texels from 60° N, 0° E, with `bits` at one texel.
    fn one_texel(x: usize, y: usize, bits: u32) -> FeatureColumns {
        let grid = StructureGrid {
            width: 41,
            height: 41,
            north: 60.0,
            west: 0.0,
            dlat: 1.0,
            dlon: 1.0,
        };
        let mut v = vec![0; 41 * 41];
        v[y * 41 + x] = bits;
        FeatureColumns::new(&grid, &v)
    }

    fn frustum(heading: f64, alt_m: f64) -> Frustum {
        let cam = Camera::new(40.0, 20.0, alt_m, heading, 0.0);
        Frustum::new(&cam, 16.0 / 9.0, (500.0, 12000.0), 800.0)
    }

    #[test]
    fn a_column_in_front_is_reached_and_behind_is_not() {
        // A cumulus texel 5° north of a camera at 40° N 20° E (row 15, column 20).
        let cu = one_texel(20, 15, flags::CELLS);
        assert_eq!(
            cu.unreached(&frustum(0.0, 6000.0)),
            flags::TOWERS | flags::STREAKS
        );
        assert_eq!(cu.unreached(&frustum(180.0, 6000.0)), REACHABLE);
        // Looking east, the texel 5° north is outside the field of view's side.
        assert_eq!(cu.unreached(&frustum(90.0, 6000.0)), REACHABLE);
    }

    #[test]
    fn range_follows_the_altitude() {
        // 12° north (1 330 km): past the horizons of a camera at 6 km and of a shell's top at
        // 12 km (700 km together, with the margins 860), within those of a camera at 80 km.
        let ci = one_texel(20, 8, flags::STREAKS);
        assert_eq!(ci.unreached(&frustum(0.0, 6000.0)), REACHABLE);
        let high = Camera::new(40.0, 20.0, 80_000.0, 0.0, -10.0);
        let f = Frustum::new(&high, 16.0 / 9.0, (500.0, 12000.0), 800.0);
        assert_eq!(ci.unreached(&f), flags::CELLS | flags::TOWERS);
    }

    #[test]
    fn a_map_without_features_leaves_them_all_out() {
        assert_eq!(
            FeatureColumns::default().unreached(&frustum(0.0, 6000.0)),
            REACHABLE
        );
        assert_eq!(
            one_texel(0, 0, 0).unreached(&frustum(0.0, 6000.0)),
            REACHABLE
        );
        // A lattice the bits do not fit: everything is reached.
        let grid = StructureGrid {
            width: 2,
            height: 2,
            north: 0.0,
            west: 0.0,
            dlat: 1.0,
            dlon: 1.0,
        };
        let odd = FeatureColumns::new(&grid, &[0; 3]);
        assert_eq!(odd.unreached(&frustum(180.0, 6000.0)), 0);
    }
}

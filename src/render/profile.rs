//! The per-cloud-type vertical profiles (DESIGN §7): a small lookup table, one row per
//! [`CloudType`] code and one column per height fraction of the cloud's own column (base 0,
//! top 1), that the march reads to shape each genus. R is the coverage profile P(h), the
//! threshold the shape noise must clear is `1 − coverage·P(h)` (so where P is 1 the cloud is as
//! wide as its coverage, and where P falls only the noise's peaks survive: domes, rolls, towers);
//! G is the density profile D(h). Row 0 (no type) is never read: the march keeps the paper's
//! analytic profile there, so maps without types render as before.

use stratus_ingest::weather::CloudType;

use super::gpu::Gpu;

/// Height samples per row: enough that linear filtering between them is smooth at the
/// sharpest ramp (a base 3 % of the column deep).
pub const LUT_WIDTH: usize = 64;
/// Rows: code 0 (none) and the ten genera.
pub const LUT_ROWS: usize = CloudType::MAX_CODE as usize + 1;

/// A profile's shape: where the coverage profile ramps up from the base and down to the top,
/// its plateau, an anvil bulge under the top, and the density level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shape {
    /// P rises from 0 at the base to the plateau at this height fraction: a flat, solid base
    /// where it is small (the condensation level).
    pub base_ramp: f32,
    /// P falls from the plateau, from here to 0 at the top: low for domed tops (only peaks
    /// reach up), high for a slab whose top is relief on a deck.
    pub top_from: f32,
    pub plateau: f32,
    /// Extra coverage in an anvil under the top (cumulonimbus): 0 for none.
    pub anvil: f32,
    /// Density level D of the genus (optical thickness relative to a stratus deck).
    pub density: f32,
    /// γ of the coverage the threshold sees, coverage^γ: calibrated so that straight down a
    /// column is more than half opaque where its coverage is above about one half, as for
    /// the paper's bands (docs/score.md; `cargo run --release --example coverage_ramp`). A
    /// profile as tall as its column lets the noise's peaks at any height through, so the
    /// raw coverage would turn opaque at a fifth.
    pub gamma: f32,
    /// Cells per shape-noise period (render::frame::SHAPE_PERIOD_M, 24 km): an integer, so
    /// the camera-relative noise position keeps wrapping seamlessly. A cumulus field is cells
    /// of a few kilometres, a stratus deck's relief tens of kilometres.
    pub freq: f32,
}

/// The genus' shape. Sources of the shapes: Schneider's Nubis height gradients (stratus a thin
/// slab, cumulus rising to near the top, cumulonimbus full height and widened at the top),
/// and ISCCP's optical-thickness classes for the density levels (docs/ingest.md). A column's
/// optical depth is about 64·D·coverage (extinction 0.04 per unit density over the 2 km the
/// march normalises each column to, times the carved noise's mean, about 0.4): the ice genera's
/// D puts a full cirrus column near τ 3 (ISCCP cirrus: τ < 3.6) and cirrostratus near 8.
pub fn shape(t: CloudType) -> Shape {
    use CloudType::*;
    let s = |base_ramp, top_from, plateau, anvil, density, gamma, freq| Shape {
        base_ramp,
        top_from,
        plateau,
        anvil,
        density,
        gamma,
        freq,
    };
    match t {
        // Thin ice, streaked by the march along the wind.
        Cirrus => s(0.2, 0.45, 0.85, 0.0, 0.3, 2.1, 2.0),
        Cirrocumulus => s(0.15, 0.4, 0.9, 0.0, 0.3, 2.1, 4.0),
        Cirrostratus => s(0.1, 0.7, 1.0, 0.0, 0.4, 2.3, 2.0),
        Altocumulus => s(0.05, 0.35, 1.0, 0.0, 0.8, 2.31, 3.0),
        Altostratus => s(0.04, 0.7, 1.0, 0.0, 0.9, 2.31, 1.0),
        Nimbostratus => s(0.03, 0.8, 1.05, 0.0, 1.0, 2.5, 1.0),
        // Rounded tops over a flat base: rolls.
        Stratocumulus => s(0.04, 0.45, 1.0, 0.0, 0.9, 2.31, 2.0),
        // A slab: the top is relief on the deck, not a lid.
        Stratus => s(0.03, 0.75, 1.0, 0.0, 1.0, 2.31, 1.0),
        // Flat base, narrowing all the way up: domes and towers.
        Cumulus => s(0.04, 0.25, 1.0, 0.0, 1.0, 2.31, 3.0),
        // Full height, narrower in the middle, widened under the top for the anvil.
        Cumulonimbus => s(0.03, 0.97, 0.85, 0.5, 1.0, 2.71, 3.0),
    }
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0).max(1e-6)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Shape {
    /// Coverage profile P at height fraction `h` (0 base, 1 top).
    pub fn coverage(&self, h: f32) -> f32 {
        let up = smoothstep(0.0, self.base_ramp, h);
        // Linear fall, not smooth: the noise's level set under a linear threshold makes domes.
        let down = 1.0 - ((h - self.top_from) / (1.0 - self.top_from).max(1e-6)).clamp(0.0, 1.0);
        let anvil = self.anvil * smoothstep(0.7, 0.9, h);
        (up * (self.plateau + anvil) * down).max(0.0)
    }

    /// Density profile D at `h`: solid from the base (60 % at once, all by mid-height), fading
    /// over the top tenth so the top is soft where the noise carves it.
    pub fn density_at(&self, h: f32) -> f32 {
        let rise = 0.6 + 0.4 * (h / 0.5).clamp(0.0, 1.0);
        self.density * rise * (1.0 - smoothstep(0.9, 1.0, h))
    }
}

/// The table's texels, row-major, RGBA: (P, D, γ, cell frequency); row 0 all zero.
pub fn table() -> Vec<[f32; 4]> {
    let mut t = vec![[0.0; 4]; LUT_WIDTH * LUT_ROWS];
    for ty in CloudType::ALL {
        let s = shape(ty);
        let row = ty.code() as usize;
        for i in 0..LUT_WIDTH {
            let h = i as f32 / (LUT_WIDTH - 1) as f32;
            t[row * LUT_WIDTH + i] = [s.coverage(h), s.density_at(h), s.gamma, s.freq];
        }
    }
    t
}

/// The table as a texture (device lifetime: it depends on nothing but the code).
pub fn texture(gpu: &Gpu) -> wgpu::Texture {
    let texels: Vec<half::f16> = table()
        .iter()
        .flat_map(|t| t.map(half::f16::from_f32))
        .collect();
    let tex = super::texture::map_texture(
        gpu,
        "cloud-type profiles",
        (LUT_WIDTH, LUT_ROWS),
        wgpu::TextureFormat::Rgba16Float,
    );
    super::texture::write(gpu, &tex, bytemuck::cast_slice(&texels), 8);
    tex
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_genus_has_a_solid_base_and_ends_at_its_top() {
        for t in CloudType::ALL {
            let s = shape(t);
            assert_eq!(s.coverage(0.0), 0.0, "{t:?}");
            assert!(s.coverage(1.0) < 1e-6, "{t:?} top");
            assert!(s.coverage(0.2) > 0.6, "{t:?} is not solid near its base");
            assert!((0.0..=1.0).contains(&s.density), "{t:?}");
        }
    }

    #[test]
    fn genera_differ_where_a_pilot_sees_it() {
        let (cu, st, cb, ci) = (
            shape(CloudType::Cumulus),
            shape(CloudType::Stratus),
            shape(CloudType::Cumulonimbus),
            shape(CloudType::Cirrus),
        );
        // Cumulus narrows with height where a stratus deck stays whole.
        assert!(cu.coverage(0.6) < 0.6 * st.coverage(0.6));
        // The anvil: a cumulonimbus is wider under its top than at mid-height.
        assert!(cb.coverage(0.9) > cb.coverage(0.5) * 1.3);
        // Cirrus is optically thin.
        assert!(ci.density_at(0.5) < 0.5 * st.density_at(0.5));
    }

    #[test]
    fn table_rows_follow_the_codes() {
        let t = table();
        assert_eq!(t.len(), LUT_WIDTH * LUT_ROWS);
        assert!(
            t[..LUT_WIDTH].iter().all(|p| *p == [0.0; 4]),
            "row 0 unused"
        );
        let cb = CloudType::Cumulonimbus.code() as usize;
        let mid = LUT_WIDTH / 2;
        assert_eq!(
            t[cb * LUT_WIDTH + mid][0],
            shape(CloudType::Cumulonimbus).coverage(mid as f32 / (LUT_WIDTH - 1) as f32)
        );
    }
}

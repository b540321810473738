//! The map's ground on the GPU (DESIGN §8): the forecast's terrain height and a surface colour
//! from its land fraction, sea ice, snow and albedo, as one texture on the ground lattice that
//! the scene's group carries (shaders/scene.wgsl marches it as a height field).

use stratus_ingest::ground::{snow_cover, Ground};

pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Albedo (linear RGB) of open water, sea ice, snow, and land for a broadband albedo of 1.
const WATER: [f32; 3] = [0.03, 0.05, 0.08];
const ICE: [f32; 3] = [0.65, 0.70, 0.75];
const SNOW: [f32; 3] = [0.80, 0.82, 0.85];
const LAND_TINT: [f32; 3] = [0.95, 1.05, 0.75];
/// The broadband albedo of snow-free land where the file gives none: with [`LAND_TINT`] about
/// [`DEFAULT_ALBEDO`], the dull land drawn where the map has no ground. Not ingest's
/// `ground::inputs::LAND_ALBEDO` (0.20), the default the map's albedo field is filled with
/// where the file has no albedo: the renderer does not read that field then (`texels`), so the
/// same land is drawn at 0.09 without a file albedo and at the file's (often about 0.2) with
/// one. Kept as it is: changing it changes the pictures (an open question of issue 29).
const LAND_ALBEDO: f32 = 0.09;
/// The ground's albedo (linear RGB) where the map has no ground: `DEFAULT_ALBEDO` in
/// shaders/scene.wgsl (render::contract checks the two agree).
pub const DEFAULT_ALBEDO: [f32; 3] = [0.08, 0.10, 0.07];

fn mix3(a: [f32; 3], b: [f32; 3], w: f32) -> [f32; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * w)
}

/// The surface colour of one texel.
pub fn albedo(land: f32, ice: f32, snow: f32, broadband: Option<f32>) -> [f32; 3] {
    let a = broadband.unwrap_or(LAND_ALBEDO).clamp(0.02, 0.9);
    let ground = LAND_TINT.map(|t| (t * a).min(0.9));
    let sea = mix3(WATER, ICE, ice.clamp(0.0, 1.0));
    let base = mix3(sea, ground, land.clamp(0.0, 1.0));
    mix3(base, SNOW, snow.clamp(0.0, 1.0) * land.clamp(0.0, 1.0))
}

/// Texels (height m, albedo r, g, b) of `g`, row 0 north, and the lattice's size.
pub fn texels(g: &Ground) -> (Vec<[half::f16; 4]>, u32, u32) {
    use stratus_ingest::ground::GroundField;
    let has_albedo = g.has(GroundField::Albedo);
    let t = (0..g.height_m.len())
        .map(|i| {
            let snow = snow_cover(g.snow_kg_m2[i] as f64) as f32;
            // The broadband albedo already holds snow where it was read.
            let (a, snow) = if has_albedo {
                (Some(g.albedo[i]), 0.0)
            } else {
                (None, snow)
            };
            let c = albedo(g.land[i], g.ice[i], snow, a);
            [g.height_m[i], c[0], c[1], c[2]].map(half::f16::from_f32)
        })
        .collect();
    (t, g.grid.width, g.grid.height)
}

/// The texture for `g` (a 1×1 sea-level stand-in without one) and its uv transform
/// `[scale_u, scale_v, offset_u, offset_v]`.
pub fn upload(gpu: &super::Gpu, g: Option<&Ground>) -> (wgpu::Texture, [f32; 4]) {
    let (texels, w, h, uv) = match g {
        Some(g) => {
            let (t, w, h) = texels(g);
            let [su, ou, sv, ov] = g.texture_transform().map(|v| v as f32);
            (t, w, h, [su, sv, ou, ov])
        }
        None => (
            vec![
                [0.0, DEFAULT_ALBEDO[0], DEFAULT_ALBEDO[1], DEFAULT_ALBEDO[2]]
                    .map(half::f16::from_f32),
            ],
            1,
            1,
            [1.0, 1.0, 0.0, 0.0],
        ),
    };
    let tex = super::texture::texture_2d(
        &gpu.device,
        "ground",
        (w, h),
        FORMAT,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
    );
    super::texture::write(gpu, &tex, bytemuck::cast_slice(&texels), 8);
    (tex, uv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surfaces_differ_as_seen_from_the_air() {
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let sea = albedo(0.0, 0.0, 0.0, None);
        let land = albedo(1.0, 0.0, 0.0, None);
        let ice = albedo(0.0, 1.0, 0.0, None);
        let snow = albedo(1.0, 0.0, 1.0, None);
        assert!(lum(sea) < lum(land) && lum(land) < lum(ice) && lum(ice) < lum(snow));
        // The file's albedo sets land's brightness.
        assert!(lum(albedo(1.0, 0.0, 0.0, Some(0.6))) > 4.0 * lum(land));
    }
}

//! The two forecast steps around the scene's time on the GPU (DESIGN §9): the later step's
//! coverage beside the earlier one's (which stays in the weather texture), both steps' layer
//! winds, and the blend's state. march.wgsl blends them per sample, semi-Lagrangian: the
//! earlier step sampled upwind by w·Δt·wind, the later downwind by (1 − w)·Δt·wind, the wind
//! (1 − w)·wind₀ + w·wind₁ at the sample's own pixel (one displacement lookup, no trajectory;
//! `stratus_ingest::series::blend` is the CPU reference that integrates one).
//!
//! The structure lattice is small (a few hundred texels a side), so base, top and the streak
//! wind are interpolated on the CPU when w changes and written into the structure textures;
//! the genus is the nearer step's, as the CPU reference takes it.
//!
//! Textures (Rgba16Float): `next`, the later step's coverage (the weather texture's size);
//! `wind`, three blocks side by side on the structure lattice, block j = layer j (low, middle,
//! high), texel (u₀, v₀, u₁, v₁) m/s. Without a pair both are 1×1 and the march never reads
//! them (`FLAG_BLEND` off).

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::structure::{sample_to_wind, MapStructure};

use super::gpu::Gpu;
use super::structure::{Prepared as StructurePrepared, StructureInfo};
use super::texture::{map_texture, write};

/// The blend at the scene's time, as the frame uniforms take it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlendNow {
    /// Fraction of the interval elapsed, 0..=1.
    pub w: f32,
    /// Seconds the earlier step is carried forward (w·Δt): it is sampled this far upwind.
    pub back_s: f32,
    /// Seconds to the later step ((1 − w)·Δt): it is sampled this far downwind.
    pub ahead_s: f32,
}

/// Which pair is on the GPU, and both steps' structure for the CPU interpolation.
pub struct Pair {
    pub t0: DateTime<Utc>,
    pub t1: DateTime<Utc>,
    structures: Option<[StructurePrepared; 2]>,
    /// The w the structure textures hold (none yet written).
    written_w: Option<f32>,
}

pub struct Blend {
    pub next: wgpu::Texture,
    pub wind: wgpu::Texture,
    pub pair: Option<Pair>,
    pub now: Option<BlendNow>,
}

impl Blend {
    /// 1×1 stand-ins: no pair.
    pub fn none(gpu: &Gpu) -> Blend {
        let one = |label| {
            let t = map_texture(gpu, label, (1, 1), wgpu::TextureFormat::Rgba16Float);
            write(gpu, &t, bytemuck::cast_slice(&[half::f16::ZERO; 4]), 8);
            t
        };
        Blend {
            next: one("blend: next step"),
            wind: one("blend: winds"),
            pair: None,
            now: None,
        }
    }

    /// Put the later step `halfs` (`w`×`h` RGBA f16) and both steps' winds on the GPU. True
    /// when the textures were kept (the map bind group stays valid).
    pub fn store(
        &mut self,
        gpu: &Gpu,
        (halfs, w, h): (&[half::f16], usize, usize),
        (a, b): (&CloudMap, &CloudMap),
        structures: Option<[StructurePrepared; 2]>,
    ) -> Result<bool, String> {
        let (t0, t1) = match (a.meta.source.valid_time, b.meta.source.valid_time) {
            (Some(t0), Some(t1)) if t1 > t0 => (t0, t1),
            _ => return Err("the two steps need valid times, the later one second".into()),
        };
        let mut kept = true;
        if (self.next.width(), self.next.height()) != (w as u32, h as u32) {
            self.next = map_texture(
                gpu,
                "blend: next step",
                (w, h),
                wgpu::TextureFormat::Rgba16Float,
            );
            kept = false;
        }
        write(gpu, &self.next, bytemuck::cast_slice(halfs), 8);
        let (ww, wh, texels) = wind_texels(a.structure.as_ref(), b.structure.as_ref());
        if (self.wind.width(), self.wind.height()) != (ww, wh) {
            self.wind = map_texture(
                gpu,
                "blend: winds",
                (ww as usize, wh as usize),
                wgpu::TextureFormat::Rgba16Float,
            );
            kept = false;
        }
        write(gpu, &self.wind, bytemuck::cast_slice(&texels), 8);
        self.pair = Some(Pair {
            t0,
            t1,
            structures,
            written_w: None,
        });
        self.now = None;
        Ok(kept)
    }

    /// The blend at `time` (held at the pair's ends), with the structure textures brought to
    /// it: `None` without a pair.
    pub fn at(
        &mut self,
        gpu: &Gpu,
        time: DateTime<Utc>,
        structure: &mut super::structure::StructureTextures,
    ) -> Option<BlendNow> {
        let pair = self.pair.as_mut()?;
        let interval = (pair.t1 - pair.t0).num_milliseconds() as f64 / 1000.0;
        let since = (time - pair.t0).num_milliseconds() as f64 / 1000.0;
        let w = (since / interval).clamp(0.0, 1.0);
        let now = BlendNow {
            w: w as f32,
            back_s: (w * interval) as f32,
            ahead_s: ((1.0 - w) * interval) as f32,
        };
        if let Some(s) = &pair.structures {
            if pair.written_w != Some(now.w) && structure.fits(&s[0]) {
                let p = interpolate(&s[0], &s[1], now.w);
                structure.store(gpu, &p);
                pair.written_w = Some(now.w);
            }
        }
        self.now = Some(now);
        Some(now)
    }
}

/// Both steps' per-layer winds as the `wind` texture's texels (width, height, RGBA f16); 1×1
/// calm where either step lacks winds or their lattices differ.
fn wind_texels(a: Option<&MapStructure>, b: Option<&MapStructure>) -> (u32, u32, Vec<half::f16>) {
    let calm = (1, 1, vec![half::f16::ZERO; 4]);
    let (Some(a), Some(b)) = (a, b) else {
        return calm;
    };
    if a.grid != b.grid || !a.is_whole() || !b.is_whole() {
        return calm;
    }
    let (w, h) = (a.grid.width as usize, a.grid.height as usize);
    let f = |v: u16| half::f16::from_f32(sample_to_wind(v) as f32);
    let mut out = vec![half::f16::ZERO; 3 * w * h * 4];
    for j in 0..h {
        for layer in 0..3 {
            for i in 0..w {
                let k = j * w + i;
                let o = (j * 3 * w + layer * w + i) * 4;
                out[o..o + 4].copy_from_slice(&[
                    f(a.wind_u[k][layer]),
                    f(a.wind_v[k][layer]),
                    f(b.wind_u[k][layer]),
                    f(b.wind_v[k][layer]),
                ]);
            }
        }
    }
    (3 * w as u32, h as u32, out)
}

/// The structure at `w` of the way from `a` to `b`: base, top and wind interpolated, the
/// genus switching from `a`'s to `b`'s texel by texel at `series::genus_switch_w` (as the CPU
/// blend), envelopes and flags the union of both (the march bounds must hold either).
pub fn interpolate(a: &StructurePrepared, b: &StructurePrepared, w: f32) -> StructurePrepared {
    let lerp = |x: &[half::f16], y: &[half::f16]| -> Vec<half::f16> {
        x.iter()
            .zip(y)
            .map(|(p, q)| half::f16::from_f32(p.to_f32() + (q.to_f32() - p.to_f32()) * w))
            .collect()
    };
    let kind: Vec<half::f16> = a.texels[2]
        .chunks(4)
        .zip(b.texels[2].chunks(4))
        .enumerate()
        .flat_map(|(k, (p, q))| {
            if w < stratus_ingest::series::genus_switch_w(k) {
                p
            } else {
                q
            }
        })
        .copied()
        .collect();
    StructurePrepared {
        width: a.width,
        height: a.height,
        texels: [
            lerp(&a.texels[0], &b.texels[0]),
            lerp(&a.texels[1], &b.texels[1]),
            kind,
            lerp(&a.texels[3], &b.texels[3]),
        ],
        info: union(&a.info, &b.info),
    }
}

fn union(a: &StructureInfo, b: &StructureInfo) -> StructureInfo {
    let span = |x: Option<(f32, f32)>, y: Option<(f32, f32)>| match (x, y) {
        (Some(p), Some(q)) => Some((p.0.min(q.0), p.1.max(q.1))),
        (p, q) => p.or(q),
    };
    StructureInfo {
        present: a.present && b.present,
        envelopes: std::array::from_fn(|k| span(a.envelopes[k], b.envelopes[k])),
        towers: span(a.towers, b.towers),
        streaks: a.streaks || b.streaks,
        cells: a.cells || b.cells,
        // The earlier step's: a series' flight gives its own, constant one (Settings).
        mean_wind: a.mean_wind,
        uv_scale: a.uv_scale,
        uv_offset: a.uv_offset,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prepared(v: f32, code: f32) -> StructurePrepared {
        let t = |x: f32| vec![half::f16::from_f32(x); 4];
        StructurePrepared {
            width: 1,
            height: 1,
            texels: [t(v), t(v + 1000.0), t(code), t(v / 100.0)],
            info: StructureInfo {
                present: true,
                envelopes: [Some((v, v + 2000.0)), None, None],
                towers: None,
                streaks: code == 1.0,
                cells: code == 9.0,
                mean_wind: [[0.0; 2]; 3],
                uv_scale: [1.0; 2],
                uv_offset: [0.0; 2],
            },
        }
    }

    #[test]
    fn structure_is_interpolated_and_the_genus_switches_between_a_quarter_and_three() {
        let (a, b) = (prepared(1000.0, 5.0), prepared(2000.0, 1.0));
        let p = interpolate(&a, &b, 0.25);
        assert_eq!(p.texels[0][0].to_f32(), 1250.0);
        assert_eq!(p.texels[1][0].to_f32(), 2250.0);
        assert_eq!(interpolate(&a, &b, 0.24).texels[2][0].to_f32(), 5.0);
        assert_eq!(interpolate(&a, &b, 0.76).texels[2][0].to_f32(), 1.0);
        // The march bounds hold both steps' columns; a genus in either is drawn.
        assert_eq!(p.info.envelopes[0], Some((1000.0, 4000.0)));
        assert!(p.info.streaks);
    }
}

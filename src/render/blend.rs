//! The two forecast steps around the scene's time on the GPU (DESIGN §9): the later step's
//! coverage beside the earlier one's (which stays in the weather texture), the guarded motion
//! between them (issue 31, `stratus_ingest::series::motion`), and the blend's state.
//! march.wgsl blends them per sample as the CPU does (`series::motion::blend`, what
//! `Series::at` makes): the motion m read where the feature passing the sample lands in the
//! later step (two fixed-point steps), the earlier step sampled at x − w·m, the later at
//! x + (1 − w)·m, then (1 − w)·a + w·b. The layer winds move only the noise (the drift).
//!
//! The structure lattice is small (a few hundred texels a side), so base, top and the streak
//! wind are interpolated on the CPU when w changes and written into the structure textures;
//! the genus is the nearer step's, as the CPU reference takes it.
//!
//! Textures (Rgba16Float): `next`, the later step's coverage (the weather texture's size);
//! `motion`, three blocks side by side on the motion's working grid (at most 256² texels,
//! covering the map as its pixels do), block j = layer j (low, middle, high), texel
//! (east, south, 0, 0): the guarded motion over the interval in map uv. Without a pair both
//! are 1×1 and the march never reads them (`FLAG_BLEND` off).

use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::series::motion::Motion;

use super::gpu::Gpu;
use super::structure::{Prepared as StructurePrepared, StructureInfo};
use super::texture::{map_texture, write};

/// The blend at the scene's time, as the frame uniforms take it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlendNow {
    /// Fraction of the interval elapsed, 0..=1.
    pub w: f32,
    /// Seconds since the earlier step (w·Δt; the blend itself reads only `w`).
    pub back_s: f32,
    /// Seconds to the later step ((1 − w)·Δt).
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
    pub motion: wgpu::Texture,
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
            motion: one("blend: motion"),
            pair: None,
            now: None,
        }
    }

    /// Put the later step `halfs` (`w`×`h` RGBA f16) and the motion between the steps on the
    /// GPU. True when the textures were kept (the map bind group stays valid).
    pub fn store(
        &mut self,
        gpu: &Gpu,
        (halfs, w, h): (&[half::f16], usize, usize),
        (a, b, motion): (&CloudMap, &CloudMap, &Motion),
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
        let (mw, mh, texels) = motion_texels(motion, w, h);
        if (self.motion.width(), self.motion.height()) != (mw, mh) {
            self.motion = map_texture(
                gpu,
                "blend: motion",
                (mw as usize, mh as usize),
                wgpu::TextureFormat::Rgba16Float,
            );
            kept = false;
        }
        write(gpu, &self.motion, bytemuck::cast_slice(&texels), 8);
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

/// The guarded motion as the `motion` texture's texels (width, height, RGBA f16): three
/// blocks of the working grid, texel (east, south) in uv of a `map_w`×`map_h` map over the
/// interval; 1×1 still where the motion has no layers.
pub fn motion_texels(motion: &Motion, map_w: usize, map_h: usize) -> (u32, u32, Vec<half::f16>) {
    let Some((w, h)) = motion.layers.first().map(|l| (l.u.w, l.u.h)) else {
        return (1, 1, vec![half::f16::ZERO; 4]);
    };
    let mut out = vec![half::f16::ZERO; 3 * w * h * 4];
    for layer in 0..3 {
        let Some(lm) = motion.layer(layer).filter(|l| (l.u.w, l.u.h) == (w, h)) else {
            continue;
        };
        let (u, v) = lm.guarded_px();
        for k in 0..w * h {
            let (i, j) = (k % w, k / w);
            let o = (j * 3 * w + layer * w + i) * 4;
            out[o] = half::f16::from_f32(u[k] / map_w as f32);
            out[o + 1] = half::f16::from_f32(v[k] / map_h as f32);
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
        columns: a.columns.union(&b.columns),
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
            columns: Default::default(),
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

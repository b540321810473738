//! Motion between forecast steps, from the steps themselves (issue 31): per layer a dense
//! motion field estimated from two steps' coverage by coarse-to-fine optical flow, and the
//! blend of the two steps along it.
//!
//! **Estimate** ([`estimate`]): each layer's coverage is reduced to a working grid of at most
//! [`WORK_PIXELS`] pixels (box mean; the GFS grid behind a map is far coarser than its pixels),
//! and a Gaussian pyramid of both steps is built. From the coarsest level down, Horn–Schunck
//! optical flow with warping: the earlier step is warped by the flow so far, the brightness
//! constancy equation is linearised there and the flow increment solved with a smoothness
//! term (Jacobi iterations), a few warps a level; the data term is robust (Charbonnier), each
//! warp's increment is bounded and kept only where it brought the steps closer, so change that
//! is not motion does not drive the flow off; the flow is carried to the next finer level
//! doubled. It is run from no motion and from the layer's region-mean wind over the interval,
//! and each result kept where it explains the change better (`best_flow`). The result `m`
//! says where the later step's coverage came from: b(x) ≈ a(x − m(x)), in map pixels per
//! interval (x east, y south).
//!
//! **Guard.** Over hours cloud forms and clears in place far more than a pattern moves
//! (docs/time.md), and optical flow explains any change, growth included, as some motion. So
//! each layer keeps a smooth weight g (0..1): the residual between the steps after moving,
//! |a(x − m) − b|², against the residual without, |a − b|², both Gaussian-averaged over
//! [`GATE_SIGMA`] working pixels; g rises from 0 where moving removes less than
//! [`GATE_LO`] of the change to 1 where it removes [`GATE_HI`] or more. The blend moves by g·m:
//! where motion does not explain the change it is the plain cross-fade.
//!
//! **Blend** ([`blend`]): at a fraction f of the interval the earlier step is sampled at
//! x − f·m and the later at x + (1 − f)·m (semi-Lagrangian, bilinear; m taken where the feature
//! passing x at f lands in the later step, by two fixed-point steps), then (1 − f)·a + f·b. At
//! f = 0 and 1 the result is the step itself. Everything but the coverage (structure, ground,
//! genus switch, valid time) is taken as [`super::advect::blend`] takes it.

use rayon::prelude::*;

use crate::cloudmap::CloudMap;
use crate::error::{IngestError, Result};
use crate::layer::LayerKind;
use crate::sample::{coverage_to_sample, COVERAGE_FULL};

use super::advect::{check_compatible, moment};

/// Largest working grid a layer's flow is estimated on, pixels.
pub const WORK_PIXELS: usize = 256 * 256;
/// The pyramid's coarsest level has at least this many pixels on its shorter side.
const MIN_LEVEL_SIDE: usize = 8;
/// Warps (re-linearisations) per pyramid level.
const WARPS: usize = 4;
/// Jacobi iterations per warp.
const ITERS: usize = 60;
/// Smoothness weight α² of Horn–Schunck, in (coverage per pixel)²: a coverage edge spanning a
/// few working pixels has a gradient ≈ 0.2–0.5, so the data term dominates at edges and the
/// smoothness term fills the flat interiors.
const ALPHA2: f32 = 0.01;
/// Weak pull towards no motion, same units (a flat patch's flow decays over ~100 pixels).
const BETA2: f32 = 1e-6;
/// Largest flow increment of one warp, pixels of its level.
const MAX_STEP: f32 = 1.0;
/// Scale of the robust (Charbonnier) data term, coverage: a residual well above it (change no
/// motion explains: growth, decay) weighs less than the smoothness.
const ROBUST_EPS: f32 = 0.05;
/// Pre-smoothing of each level before its gradients, working pixels.
const PRE_SIGMA: f32 = 1.0;
/// Neighbourhood of the guard's residuals, working pixels (σ of the Gaussian).
pub const GATE_SIGMA: f32 = 8.0;
/// Neighbourhood over which the two flows' residuals are compared, working pixels.
const PICK_SIGMA: f32 = 4.0;
/// Fraction of the change that moving must remove before any motion is used…
pub const GATE_LO: f32 = 0.4;
/// …and from which it is used in full.
pub const GATE_HI: f32 = 0.8;

/// A scalar field on a grid, row-major, row 0 north; x wraps when the region spans all
/// longitudes.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub w: usize,
    pub h: usize,
    pub wrap: bool,
    pub v: Vec<f32>,
}

impl Grid {
    fn filled(w: usize, h: usize, wrap: bool, x: f32) -> Grid {
        Grid {
            w,
            h,
            wrap,
            v: vec![x; w * h],
        }
    }

    fn col(&self, i: isize) -> usize {
        if self.wrap {
            i.rem_euclid(self.w as isize) as usize
        } else {
            i.clamp(0, self.w as isize - 1) as usize
        }
    }

    fn at(&self, i: isize, j: isize) -> f32 {
        let j = j.clamp(0, self.h as isize - 1) as usize;
        self.v[j * self.w + self.col(i)]
    }

    /// Bilinear at (x, y), pixel centres at whole numbers; clamped (or wrapped) at the edges.
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let (i, j) = (x0 as isize, y0 as isize);
        let top = self.at(i, j) * (1.0 - tx) + self.at(i + 1, j) * tx;
        let bottom = self.at(i, j + 1) * (1.0 - tx) + self.at(i + 1, j + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// A grid of the same shape, pixel (i, j) from `f(i, j)` (rows in parallel).
    fn map(&self, f: impl Fn(usize, usize) -> f32 + Sync) -> Grid {
        let mut v = vec![0.0; self.w * self.h];
        v.par_chunks_mut(self.w).enumerate().for_each(|(j, row)| {
            for (i, x) in row.iter_mut().enumerate() {
                *x = f(i, j);
            }
        });
        Grid { v, ..*self }
    }

    /// Separable Gaussian blur of standard deviation `sigma` pixels.
    fn blur(&self, sigma: f32) -> Grid {
        if sigma <= 0.0 {
            return self.clone();
        }
        let r = (3.0 * sigma).ceil() as isize;
        let k: Vec<f32> = (-r..=r)
            .map(|d| (-(d * d) as f32 / (2.0 * sigma * sigma)).exp())
            .collect();
        let sum: f32 = k.iter().sum();
        let k: Vec<f32> = k.iter().map(|x| x / sum).collect();
        let across = self.map(|i, j| {
            (-r..=r)
                .zip(&k)
                .map(|(d, w)| w * self.at(i as isize + d, j as isize))
                .sum()
        });
        across.map(|i, j| {
            (-r..=r)
                .zip(&k)
                .map(|(d, w)| w * across.at(i as isize, j as isize + d))
                .sum()
        })
    }

    /// This grid resampled to `w`×`h` (bilinear between pixel centres, each new pixel's centre
    /// at its place in the old grid); callers blur first when shrinking.
    fn resized(&self, w: usize, h: usize) -> Grid {
        let (sx, sy) = (self.w as f32 / w as f32, self.h as f32 / h as f32);
        Grid::filled(w, h, self.wrap, 0.0)
            .map(|i, j| self.sample((i as f32 + 0.5) * sx - 0.5, (j as f32 + 0.5) * sy - 0.5))
    }

    /// Mean over `f`×`f` blocks (the last block of a row or column may be partial).
    fn box_down(&self, f: usize) -> Grid {
        if f <= 1 {
            return self.clone();
        }
        let (w, h) = (self.w.div_ceil(f), self.h.div_ceil(f));
        Grid::filled(w, h, self.wrap, 0.0).map(|i, j| {
            let (mut s, mut n) = (0.0, 0.0);
            for y in j * f..((j + 1) * f).min(self.h) {
                for x in i * f..((i + 1) * f).min(self.w) {
                    s += self.v[y * self.w + x];
                    n += 1.0;
                }
            }
            s / n
        })
    }
}

/// One layer's motion: the flow (working pixels per interval, x east, y south) and the guard
/// weight, on the working grid, with the map size they belong to.
#[derive(Debug, Clone)]
pub struct LayerMotion {
    pub kind: LayerKind,
    pub channel: usize,
    pub u: Grid,
    pub v: Grid,
    pub gate: Grid,
    /// Map size the working grid was made from.
    pub map_w: usize,
    pub map_h: usize,
}

impl LayerMotion {
    /// The guarded motion (g·m) at map pixel centre (x, y), in map pixels per interval.
    pub fn at(&self, x: f32, y: f32) -> (f32, f32) {
        let (sx, sy) = (
            self.u.w as f32 / self.map_w as f32,
            self.u.h as f32 / self.map_h as f32,
        );
        let (gx, gy) = ((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5);
        let g = self.gate.sample(gx, gy);
        (
            g * self.u.sample(gx, gy) / sx,
            g * self.v.sample(gx, gy) / sy,
        )
    }

    /// The guarded motion g·m at each working-grid pixel, map pixels per interval (east,
    /// south): what is stored with a series and put on the GPU.
    pub fn guarded_px(&self) -> (Vec<f32>, Vec<f32>) {
        let (sx, sy) = (
            self.u.w as f32 / self.map_w as f32,
            self.u.h as f32 / self.map_h as f32,
        );
        let g = |k: usize| {
            let (i, j) = (k % self.u.w, k / self.u.w);
            let (gx, gy) = (
                (i as f32 + 0.5) * self.gate.w as f32 / self.u.w as f32 - 0.5,
                (j as f32 + 0.5) * self.gate.h as f32 / self.u.h as f32 - 0.5,
            );
            self.gate.sample(gx, gy)
        };
        (0..self.u.v.len())
            .map(|k| (g(k) * self.u.v[k] / sx, g(k) * self.v.v[k] / sy))
            .unzip()
    }

    /// A layer's motion from its guarded field (map pixels per interval on a `w`×`h` working
    /// grid, as [`LayerMotion::guarded_px`] gives it); the guard is then 1 everywhere.
    pub fn from_guarded_px(
        (kind, channel): (LayerKind, usize),
        (w, h, wrap): (usize, usize, bool),
        (u, v): (Vec<f32>, Vec<f32>),
        (map_w, map_h): (usize, usize),
    ) -> LayerMotion {
        let (sx, sy) = (w as f32 / map_w as f32, h as f32 / map_h as f32);
        let grid = |v: Vec<f32>, s: f32| Grid {
            w,
            h,
            wrap,
            v: v.into_iter().map(|x| x * s).collect(),
        };
        LayerMotion {
            kind,
            channel,
            u: grid(u, sx),
            v: grid(v, sy),
            gate: Grid::filled(w, h, wrap, 1.0),
            map_w,
            map_h,
        }
    }

    /// Mean guarded displacement over the layer, map pixels per interval, and the mean guard.
    pub fn summary(&self) -> (f32, f32, f32) {
        let n = self.u.v.len() as f32;
        let (sx, sy) = (
            self.u.w as f32 / self.map_w as f32,
            self.u.h as f32 / self.map_h as f32,
        );
        let mut s = (0.0, 0.0, 0.0);
        for k in 0..self.u.v.len() {
            let g = self.gate.v[k];
            s.0 += g * self.u.v[k] / sx;
            s.1 += g * self.v.v[k] / sy;
            s.2 += g;
        }
        (s.0 / n, s.1 / n, s.2 / n)
    }
}

/// The motion of every layer of a pair of steps.
#[derive(Debug, Clone)]
pub struct Motion {
    pub layers: Vec<LayerMotion>,
}

impl Motion {
    /// No motion (the blend is then the plain cross-fade).
    pub fn none(map: &CloudMap) -> Motion {
        let (w, h) = (map.width(), map.height());
        let layers = map
            .meta
            .layers
            .iter()
            .map(|l| {
                let z = Grid::filled(1, 1, false, 0.0);
                LayerMotion {
                    kind: l.kind,
                    channel: l.channel,
                    u: z.clone(),
                    v: z.clone(),
                    gate: z,
                    map_w: w,
                    map_h: h,
                }
            })
            .collect();
        Motion { layers }
    }

    /// The layer of channel `c`, if it has one.
    pub fn layer(&self, c: usize) -> Option<&LayerMotion> {
        self.layers.iter().find(|l| l.channel == c)
    }

    /// The same motion with each layer's guard multiplied in (guard 1 everywhere): what a
    /// stored motion reads back as, so the blend of a motion estimated at load and of one
    /// read from the series is made by the same arithmetic (and the GPU's, which samples the
    /// guarded field, agrees with both).
    pub fn baked(&self) -> Motion {
        let layers = self
            .layers
            .iter()
            .map(|l| {
                LayerMotion::from_guarded_px(
                    (l.kind, l.channel),
                    (l.u.w, l.u.h, l.u.wrap),
                    l.guarded_px(),
                    (l.map_w, l.map_h),
                )
            })
            .collect();
        Motion { layers }
    }

    /// The largest guarded displacement of any layer, map pixels per interval.
    pub fn max_shift_px(&self) -> f32 {
        self.layers
            .iter()
            .flat_map(|l| {
                let (u, v) = l.guarded_px();
                u.into_iter().zip(v).map(|(x, y)| x.hypot(y))
            })
            .fold(0.0, f32::max)
    }
}

/// Channel `c` of `map` as a coverage grid (0..1).
fn layer_grid(map: &CloudMap, c: usize) -> Grid {
    Grid {
        w: map.width(),
        h: map.height(),
        wrap: map.meta.region.lon_span() >= 360.0 - 1e-9,
        v: map
            .texels
            .iter()
            .map(|t| (t[c] as f64 / COVERAGE_FULL) as f32)
            .collect(),
    }
}

/// Block size that brings a `w`×`h` map to at most [`WORK_PIXELS`].
fn work_factor(w: usize, h: usize) -> usize {
    let mut f = 1;
    while w.div_ceil(f) * h.div_ceil(f) > WORK_PIXELS {
        f += 1;
    }
    f
}

/// The working grid a `w`×`h` map's motion is estimated (and stored) on.
pub fn work_size(w: usize, h: usize) -> (usize, usize) {
    let f = work_factor(w, h);
    (w.div_ceil(f), h.div_ceil(f))
}

/// `a` warped by the flow: a(x − m(x)).
fn warp(a: &Grid, u: &Grid, v: &Grid) -> Grid {
    a.map(|i, j| {
        let k = j * a.w + i;
        a.sample(i as f32 - u.v[k], j as f32 - v.v[k])
    })
}

/// Whether (x, y) lies on the grid (east–west always, for a grid all round).
fn inside(g: &Grid, x: f32, y: f32) -> bool {
    let half = -0.5..=(g.h as f32 - 0.5);
    half.contains(&y) && (g.wrap || (-0.5..=(g.w as f32 - 0.5)).contains(&x))
}

/// (p − q)² per pixel.
fn residual(p: &Grid, q: &Grid) -> Grid {
    Grid {
        v: p.v
            .iter()
            .zip(&q.v)
            .map(|(x, y)| (x - y) * (x - y))
            .collect(),
        ..p.clone()
    }
}

/// 3×3 median of `g` (removes the lone outliers the linearisation leaves; "secrets of optical
/// flow").
fn median3(g: &Grid) -> Grid {
    g.map(|i, j| {
        let (i, j) = (i as isize, j as isize);
        let mut n = [0.0f32; 9];
        for (k, x) in n.iter_mut().enumerate() {
            *x = g.at(i + k as isize % 3 - 1, j + k as isize / 3 - 1);
        }
        n.sort_by(f32::total_cmp);
        n[4]
    })
}

/// Horn–Schunck with warping on one pyramid level, refining the flow (`u`, `v`) in place.
/// Each warp solves, per pixel, the linearised data term, the smoothness term (α², towards
/// the neighbours' mean) and a weak pull towards no motion (β², so change that no motion
/// explains, growth, does not push the flow without bound); the increment of one warp is
/// held to [`MAX_STEP`] pixels (the linearisation holds about that far), and a pixel whose
/// warped source lies off the grid gives no data.
fn refine(a: &Grid, b: &Grid, u: &mut Grid, v: &mut Grid) {
    let (w, h) = (a.w, a.h);
    for _ in 0..WARPS {
        let aw = warp(a, u, v);
        let mean = Grid {
            v: aw.v.iter().zip(&b.v).map(|(x, y)| 0.5 * (x + y)).collect(),
            ..aw.clone()
        };
        let off = |k: usize| !inside(a, (k % w) as f32 - u.v[k], (k / w) as f32 - v.v[k]);
        let ix = mean.map(|i, j| {
            let (i, j) = (i as isize, j as isize);
            0.5 * (mean.at(i + 1, j) - mean.at(i - 1, j))
        });
        let iy = mean.map(|i, j| {
            let (i, j) = (i as isize, j as isize);
            0.5 * (mean.at(i, j + 1) - mean.at(i, j - 1))
        });
        let data: Vec<(f32, f32, f32)> = (0..w * h)
            .map(|k| {
                if off(k) {
                    (0.0, 0.0, 0.0)
                } else {
                    (ix.v[k], iy.v[k], b.v[k] - aw.v[k])
                }
            })
            .collect();
        let (u0, v0) = (u.clone(), v.clone());
        let s = ALPHA2 + BETA2;
        let mut weight = vec![1.0f32; w * h];
        for it in 0..ITERS {
            if it % 10 == 0 {
                // Lagged robust weights of the data term, from the residual of the flow so far.
                weight.par_iter_mut().enumerate().for_each(|(k, wd)| {
                    let (gx, gy, gt) = data[k];
                    let r = gt + gx * (u.v[k] - u0.v[k]) + gy * (v.v[k] - v0.v[k]);
                    *wd = ROBUST_EPS / (r * r + ROBUST_EPS * ROBUST_EPS).sqrt();
                });
            }
            let avg = |f: &Grid, i: usize, j: usize| {
                let (i, j) = (i as isize, j as isize);
                0.25 * (f.at(i - 1, j) + f.at(i + 1, j) + f.at(i, j - 1) + f.at(i, j + 1))
            };
            let step = |i: usize, j: usize| {
                let k = j * w + i;
                let (gx, gy, gt) = data[k];
                let (gx, gy, gt) = {
                    // The weight scales the data term: √weight on each of its factors.
                    let q = weight[k].sqrt();
                    (q * gx, q * gy, q * gt)
                };
                let c = gt - gx * u0.v[k] - gy * v0.v[k];
                let (r1, r2) = (
                    ALPHA2 * avg(u, i, j) - gx * c,
                    ALPHA2 * avg(v, i, j) - gy * c,
                );
                let det = s * (s + gx * gx + gy * gy);
                (
                    ((gy * gy + s) * r1 - gx * gy * r2) / det,
                    ((gx * gx + s) * r2 - gx * gy * r1) / det,
                )
            };
            let mut nu = vec![0.0; w * h];
            let mut nv = vec![0.0; w * h];
            nu.par_chunks_mut(w)
                .zip(nv.par_chunks_mut(w))
                .enumerate()
                .for_each(|(j, (ru, rv))| {
                    for i in 0..w {
                        (ru[i], rv[i]) = step(i, j);
                    }
                });
            u.v = nu;
            v.v = nv;
        }
        for (f, f0) in [(&mut *u, &u0), (&mut *v, &v0)] {
            for (x, x0) in f.v.iter_mut().zip(&f0.v) {
                *x = x0 + (*x - x0).clamp(-MAX_STEP, MAX_STEP);
            }
            *f = median3(f);
        }
        // Keep the warp only where it brought the steps closer (a local line search: the
        // linearisation can overshoot where the change is not motion).
        let before = residual(&aw, b).blur(1.0);
        let after = residual(&warp(a, u, v), b).blur(1.0);
        for k in 0..w * h {
            if after.v[k] > before.v[k] {
                u.v[k] = u0.v[k];
                v.v[k] = v0.v[k];
            }
        }
    }
}

/// The flow taking `a` to `b` (b(x) ≈ a(x − m(x))) on their grid, coarse to fine, starting
/// from the uniform `first_guess` (pixels of this grid per interval).
pub fn flow(a: &Grid, b: &Grid, first_guess: (f32, f32)) -> (Grid, Grid) {
    let mut pa = vec![a.blur(PRE_SIGMA)];
    let mut pb = vec![b.blur(PRE_SIGMA)];
    loop {
        let top = pa.last().expect("the pyramid has its base");
        let (w, h) = (top.w.div_ceil(2), top.h.div_ceil(2));
        if w.min(h) < MIN_LEVEL_SIDE {
            break;
        }
        let down = |g: &Grid| g.blur(1.0).resized(w, h);
        let (na, nb) = (down(top), down(pb.last().expect("as deep as pa")));
        pa.push(na);
        pb.push(nb);
    }
    let coarsest = pa.last().expect("the pyramid has its base");
    let (sx, sy) = (
        coarsest.w as f32 / a.w as f32,
        coarsest.h as f32 / a.h as f32,
    );
    let mut u = Grid::filled(coarsest.w, coarsest.h, a.wrap, first_guess.0 * sx);
    let mut v = Grid::filled(coarsest.w, coarsest.h, a.wrap, first_guess.1 * sy);
    for (la, lb) in pa.iter().zip(&pb).rev() {
        if (u.w, u.h) != (la.w, la.h) {
            let (sx, sy) = (la.w as f32 / u.w as f32, la.h as f32 / u.h as f32);
            u = u.resized(la.w, la.h);
            v = v.resized(la.w, la.h);
            u.v.iter_mut().for_each(|x| *x *= sx);
            v.v.iter_mut().for_each(|x| *x *= sy);
        }
        refine(la, lb, &mut u, &mut v);
    }
    (u, v)
}

/// The flow from no motion and the flow from the wind's first guess, each kept where it
/// explains the change better (smoothed residuals, a soft choice so the field stays smooth):
/// a pattern may move with the wind or not at all (docs/time.md), and a uniform first guess
/// as large as a third of the region leaves parts of it where the other start is nearer.
fn best_flow(a: &Grid, b: &Grid, guess: (f32, f32)) -> (Grid, Grid) {
    let (u0, v0) = flow(a, b, (0.0, 0.0));
    if guess == (0.0, 0.0) {
        return (u0, v0);
    }
    let (u1, v1) = flow(a, b, guess);
    let r0 = residual(&warp(a, &u0, &v0), b).blur(PICK_SIGMA);
    let r1 = residual(&warp(a, &u1, &v1), b).blur(PICK_SIGMA);
    let pick: Vec<f32> =
        r0.v.iter()
            .zip(&r1.v)
            .map(|(p, q)| {
                let t = (0.5 + 2.5 * (p - q) / (p + q + 1e-6)).clamp(0.0, 1.0);
                t * t * (3.0 - 2.0 * t)
            })
            .collect();
    let mix = |f0: &Grid, f1: &Grid| Grid {
        v: f0
            .v
            .iter()
            .zip(&f1.v)
            .zip(&pick)
            .map(|((x, y), t)| x + t * (y - x))
            .collect(),
        ..f0.clone()
    };
    (mix(&u0, &u1), mix(&v0, &v1))
}

/// The guard weight: how much of the change between `a` and `b` moving by (`u`, `v`) removes,
/// per neighbourhood, mapped to 0..1 (module doc).
pub fn gate(a: &Grid, b: &Grid, u: &Grid, v: &Grid) -> Grid {
    let aw = warp(a, u, v);
    let sq = |x: &Grid, y: &Grid| Grid {
        v: x.v
            .iter()
            .zip(&y.v)
            .map(|(p, q)| (p - q) * (p - q))
            .collect(),
        ..x.clone()
    };
    let moved = sq(&aw, b).blur(GATE_SIGMA);
    let still = sq(a, b).blur(GATE_SIGMA);
    let (lo, hi) = (GATE_LO, GATE_HI);
    Grid {
        v: moved
            .v
            .iter()
            .zip(&still.v)
            .map(|(r1, r0)| {
                let removed = 1.0 - r1 / (r0 + 1e-6);
                let t = ((removed - lo) / (hi - lo)).clamp(0.0, 1.0);
                t * t * (3.0 - 2.0 * t)
            })
            .collect(),
        ..moved
    }
}

/// Per layer, the region-mean wind of both steps carried over `interval_s`, in map pixels
/// (east, south): the flow's first guess. Zero without wind images.
fn wind_guess(a: &CloudMap, b: &CloudMap, interval_s: f64) -> [(f32, f32); 3] {
    let (wa, wb) = (
        super::winds::map_mean_wind(a),
        super::winds::map_mean_wind(b),
    );
    let r = &a.meta.region;
    let lat = 0.5 * (r.north + r.south);
    let deg = 180.0 / std::f64::consts::PI / super::advect::EARTH_RADIUS_M;
    let px_lon = r.lon_span() / a.width() as f64;
    let px_lat = (r.north - r.south) / a.height() as f64;
    std::array::from_fn(|c| {
        let (u, v) = (0.5 * (wa[c][0] + wb[c][0]), 0.5 * (wa[c][1] + wb[c][1]));
        let cos = lat.to_radians().cos().max(0.05);
        (
            (u * interval_s * deg / cos / px_lon) as f32,
            (-v * interval_s * deg / px_lat) as f32,
        )
    })
}

/// Per layer, the motion taking step `a`'s coverage to step `b`'s (`interval_s` later), with
/// its guard; the layer's region-mean wind over the interval is the first guess.
pub fn estimate(a: &CloudMap, b: &CloudMap, interval_s: f64) -> Result<Motion> {
    check_compatible(a, b).map_err(IngestError::BadMap)?;
    let f = work_factor(a.width(), a.height());
    let guess = wind_guess(a, b, interval_s);
    let layers = a
        .meta
        .layers
        .par_iter()
        .map(|l| {
            let ga = layer_grid(a, l.channel).box_down(f);
            let gb = layer_grid(b, l.channel).box_down(f);
            let g = guess.get(l.channel).copied().unwrap_or((0.0, 0.0));
            let (u, v) = best_flow(&ga, &gb, (g.0 / f as f32, g.1 / f as f32));
            let gate = gate(&ga, &gb, &u, &v);
            LayerMotion {
                kind: l.kind,
                channel: l.channel,
                u,
                v,
                gate,
                map_w: a.width(),
                map_h: a.height(),
            }
        })
        .collect();
    Ok(Motion { layers })
}

/// The moment a fraction `w` of the way from step `a` to step `b` (`interval_s` apart), each
/// layer moved along `motion` (module doc); the rest of the map as [`super::advect::blend`]
/// makes it.
pub fn blend(
    a: &CloudMap,
    b: &CloudMap,
    w: f64,
    interval_s: f64,
    motion: &Motion,
) -> Result<CloudMap> {
    check_compatible(a, b).map_err(IngestError::BadMap)?;
    if !(w.is_finite() && (0.0..=1.0).contains(&w)) {
        return Err(IngestError::BadMap(format!(
            "blend weight {w} is outside 0..=1"
        )));
    }
    let (mw, mh) = (a.width(), a.height());
    let grids: Vec<(usize, Grid, Grid)> = a
        .meta
        .layers
        .iter()
        .map(|l| {
            (
                l.channel,
                layer_grid(a, l.channel),
                layer_grid(b, l.channel),
            )
        })
        .collect();
    let f = w as f32;
    let mut texels = vec![[0u16; 4]; mw * mh];
    texels.par_chunks_mut(mw).enumerate().for_each(|(j, row)| {
        for (i, t) in row.iter_mut().enumerate() {
            let (x, y) = (i as f32, j as f32);
            for (c, ga, gb) in &grids {
                let m = motion.layer(*c).map_or((0.0, 0.0), |lm| {
                    // The motion of the feature passing x now, read where it lands in b.
                    let mut m = lm.at(x, y);
                    for _ in 0..2 {
                        m = lm.at(x + (1.0 - f) * m.0, y + (1.0 - f) * m.1);
                    }
                    m
                });
                let ca = ga.sample(x - f * m.0, y - f * m.1);
                let cb = gb.sample(x + (1.0 - f) * m.0, y + (1.0 - f) * m.1);
                t[*c] = coverage_to_sample(f64::from((1.0 - f) * ca + f * cb));
            }
            t[3] = t[0].max(t[1]).max(t[2]);
        }
    });
    Ok(moment(a, b, w, interval_s, texels))
}

/// `a`'s coverage carried the whole interval along `motion` (each layer sampled at x − g·m(x));
/// the rest of `a` unchanged. How much of the later step the motion explains (a fit, not a
/// forecast: the motion was estimated from the later step).
pub fn carried(a: &CloudMap, motion: &Motion) -> CloudMap {
    let (mw, mh) = (a.width(), a.height());
    let mut out = a.clone();
    let grids: Vec<(usize, Grid)> = a
        .meta
        .layers
        .iter()
        .map(|l| (l.channel, layer_grid(a, l.channel)))
        .collect();
    out.texels
        .par_chunks_mut(mw)
        .enumerate()
        .for_each(|(j, row)| {
            for (i, t) in row.iter_mut().enumerate() {
                let (x, y) = (i as f32, j as f32);
                for (c, g) in &grids {
                    let m = motion.layer(*c).map_or((0.0, 0.0), |lm| lm.at(x, y));
                    t[*c] = coverage_to_sample(f64::from(g.sample(x - m.0, y - m.1)));
                }
                t[3] = t[0].max(t[1]).max(t[2]);
            }
        });
    debug_assert_eq!(out.texels.len(), mw * mh);
    crate::pipeline::fill_stats(&mut out.meta, &out.texels);
    out
}

/// The plain cross-fade of `a` and `b` at `w`: no motion.
pub fn crossfade(a: &CloudMap, b: &CloudMap, w: f64, interval_s: f64) -> Result<CloudMap> {
    blend(a, b, w, interval_s, &Motion::none(a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::meta::LayerKind;
    use crate::region::Region;

    /// A cloud-like field: a few soft blobs of different sizes, cover 0..1.
    fn clouds(x: f32, y: f32) -> f32 {
        let blobs = [
            (30.0, 25.0, 9.0, 1.0),
            (70.0, 40.0, 14.0, 0.9),
            (45.0, 70.0, 7.0, 1.0),
            (90.0, 80.0, 11.0, 0.8),
            (20.0, 85.0, 6.0, 0.7),
        ];
        let s: f32 = blobs
            .iter()
            .map(|&(cx, cy, r, a)| {
                let d2 = (x - cx).powi(2) + (y - cy).powi(2);
                a * (-d2 / (2.0 * r * r)).exp()
            })
            .sum();
        (1.6 * s).min(1.0)
    }

    fn grid(w: usize, h: usize, f: impl Fn(f32, f32) -> f32 + Sync) -> Grid {
        Grid::filled(w, h, false, 0.0).map(|i, j| f(i as f32, j as f32))
    }

    #[test]
    fn a_field_shifted_by_a_known_displacement_is_recovered() {
        let (dx, dy) = (6.0, -4.0);
        let a = grid(128, 112, clouds);
        let b = grid(128, 112, |x, y| clouds(x - dx, y - dy));
        let (u, v) = flow(&a, &b, (0.0, 0.0));
        let g = gate(&a, &b, &u, &v);
        // Where there is cloud to see move (either step, inside the frame).
        let (mut su, mut sv, mut sg, mut n) = (0.0, 0.0, 0.0, 0.0);
        for j in 12..100 {
            for i in 12..116 {
                let k = j * 128 + i;
                if a.v[k].max(b.v[k]) > 0.3 {
                    su += u.v[k];
                    sv += v.v[k];
                    sg += g.v[k];
                    n += 1.0;
                }
            }
        }
        let (mu, mv, mg) = (su / n, sv / n, sg / n);
        assert!(
            (mu - dx).abs() < 0.5 && (mv - dy).abs() < 0.5,
            "mean flow ({mu}, {mv}) for a shift ({dx}, {dy})"
        );
        assert!(mg > 0.9, "guard {mg} where the motion explains the change");
    }

    #[test]
    fn pure_growth_keeps_the_cross_fade() {
        // The same clouds thickening in place: no motion explains that.
        let a = grid(128, 112, |x, y| 0.35 * clouds(x, y));
        let b = grid(128, 112, clouds);
        let (u, v) = flow(&a, &b, (0.0, 0.0));
        let g = gate(&a, &b, &u, &v);
        let cloudy: Vec<usize> = (0..a.v.len()).filter(|&k| b.v[k] > 0.3).collect();
        let mg = cloudy.iter().map(|&k| g.v[k]).sum::<f32>() / cloudy.len() as f32;
        let moved = cloudy
            .iter()
            .map(|&k| g.v[k] * u.v[k].hypot(v.v[k]))
            .fold(0.0f32, f32::max);
        assert!(mg < 0.05, "mean guard {mg} over growing cloud");
        // A pixel or so at the rims (thickening reads a little as spreading), none inside.
        assert!(
            moved < 1.5,
            "guarded motion up to {moved} px over growing cloud"
        );
    }

    /// A map of the blob field over a 0.1° equatorial region, moved by (`dx`, `dy`) pixels.
    fn map(dx: f32, dy: f32, growth: f32) -> CloudMap {
        let r = Region::parse("-6,6,0,12").unwrap();
        let t = crate::meta::parse_time("2020-08-04T12:00:00Z").unwrap();
        let bands = [(LayerKind::High, 8000.0, 10000.0)];
        CloudMap::from_fn(r, 120, 120, &bands, t, |lat, lon| {
            let (x, y) = ((lon * 10.0 - 0.5) as f32, ((6.0 - lat) * 10.0 - 0.5) as f32);
            [0.0, 0.0, f64::from(growth * clouds(x - dx, y - dy))]
        })
    }

    fn dice(a: &CloudMap, b: &CloudMap, c: usize) -> f64 {
        let half = (COVERAGE_FULL / 2.0) as u16;
        let (mut both, mut n) = (0.0, 0.0);
        for (p, q) in a.texels.iter().zip(&b.texels) {
            let (x, y) = (p[c] > half, q[c] > half);
            both += f64::from(u8::from(x && y));
            n += f64::from(u8::from(x)) + f64::from(u8::from(y));
        }
        2.0 * both / n
    }

    #[test]
    fn the_blend_moves_a_pattern_half_way_and_keeps_the_steps_at_the_ends() {
        let (a, mid, mut b) = (map(0.0, 0.0, 1.0), map(8.0, 5.0, 1.0), map(16.0, 10.0, 1.0));
        let six = chrono::Duration::hours(6);
        b.meta.source.valid_time = b.meta.source.valid_time.map(|t| t + six);
        let m = estimate(&a, &b, 6.0 * 3600.0).unwrap();
        let moved = blend(&a, &b, 0.5, 6.0 * 3600.0, &m).unwrap();
        let faded = crossfade(&a, &b, 0.5, 6.0 * 3600.0).unwrap();
        let (dm, dc) = (dice(&moved, &mid, 2), dice(&faded, &mid, 2));
        assert!(dm > 0.95, "moved half-way: Dice {dm}");
        assert!(dc < 0.9, "the cross-fade shows two ghosts: Dice {dc}");
        // The valid time is the moment's, the structure the nearer step's.
        assert_eq!(
            moved.meta.source.valid_time,
            a.meta
                .source
                .valid_time
                .map(|t| t + chrono::Duration::hours(3))
        );
        for (w, step) in [(0.0, &a), (1.0, &b)] {
            let at = blend(&a, &b, w, 6.0 * 3600.0, &m).unwrap();
            assert_eq!(at.texels, step.texels, "w = {w}");
        }
    }

    #[test]
    fn growth_in_place_blends_as_the_cross_fade() {
        let (a, b) = (map(0.0, 0.0, 0.35), map(0.0, 0.0, 1.0));
        let m = estimate(&a, &b, 6.0 * 3600.0).unwrap();
        let moved = blend(&a, &b, 0.5, 6.0 * 3600.0, &m).unwrap();
        let faded = crossfade(&a, &b, 0.5, 6.0 * 3600.0).unwrap();
        let worst = moved
            .texels
            .iter()
            .zip(&faded.texels)
            .map(|(p, q)| p[2].abs_diff(q[2]))
            .max()
            .unwrap();
        assert!(
            (worst as f64) < 0.02 * COVERAGE_FULL,
            "largest difference from the cross-fade {worst}"
        );
    }

    #[test]
    fn a_region_all_round_wraps_east_west() {
        let mut a = grid(96, 40, |x, y| clouds(x + 60.0, y + 30.0));
        a.wrap = true;
        let at = |x: f32| a.sample(x, 20.0);
        assert!((at(-0.5) - 0.5 * (a.v[20 * 96] + a.v[20 * 96 + 95])).abs() < 1e-6);
        assert!((at(96.0) - a.v[20 * 96]).abs() < 1e-6);
    }
}

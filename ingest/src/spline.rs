//! Resampling a lat/lon field onto a region's pixel grid (DESIGN §1.3).
//!
//! Every method is a separable piecewise cubic in Hermite form, in grid-index coordinates
//! (GFS grids are uniform, so index space is an affine image of lat/lon and the spline is the
//! same). The methods differ only in the node slopes:
//! - `Spline`: the C² interpolating cubic spline with not-a-knot ends — the same function as
//!   FITPACK's `RectBivariateSpline(kx=3, ky=3, s=0)`, whose knots are the data points less the
//!   second and second-to-last, i.e. not-a-knot. The tensor product of two 1-D interpolating
//!   splines is the 2-D interpolant, so rows then columns gives exactly the bivariate spline.
//! - `CatmullRom`: central-difference slopes (C¹, local).
//! - `Bilinear` / `Nearest`: slopes unused; linear or step weights.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Columns copied from the far side of a global grid on each side, so the spline near the
/// seam sees its true neighbours (the reference pipeline pads by 8 too).
pub const WRAP_PAD: usize = 8;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Interp {
    #[default]
    Spline,
    CatmullRom,
    Bilinear,
    Nearest,
}

impl Interp {
    pub const ALL: [Interp; 4] = [
        Interp::Spline,
        Interp::CatmullRom,
        Interp::Bilinear,
        Interp::Nearest,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Interp::Spline => "spline",
            Interp::CatmullRom => "catmull-rom",
            Interp::Bilinear => "bilinear",
            Interp::Nearest => "nearest",
        }
    }

    /// Node slopes (d y / d index) for `y`, written to `s`.
    pub fn slopes(self, y: &[f64], s: &mut [f64]) {
        match self {
            Interp::Spline => not_a_knot_slopes(y, s),
            Interp::CatmullRom => catmull_rom_slopes(y, s),
            Interp::Bilinear | Interp::Nearest => s.fill(0.0),
        }
    }

    /// Weights on (y0, y1, s0, s1) at fraction `t` ∈ \[0, 1\] of an interval.
    pub fn weights(self, t: f64) -> [f64; 4] {
        match self {
            Interp::Spline | Interp::CatmullRom => {
                let t2 = t * t;
                let t3 = t2 * t;
                [
                    2.0 * t3 - 3.0 * t2 + 1.0,
                    -2.0 * t3 + 3.0 * t2,
                    t3 - 2.0 * t2 + t,
                    t3 - t2,
                ]
            }
            Interp::Bilinear => [1.0 - t, t, 0.0, 0.0],
            Interp::Nearest => {
                if t < 0.5 {
                    [1.0, 0.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0, 0.0]
                }
            }
        }
    }
}

impl fmt::Display for Interp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Interp {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Interp::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                format!("unknown interpolation '{s}' (spline, catmull-rom, bilinear, nearest)")
            })
    }
}

/// Slopes of the not-a-knot cubic spline through `y` at unit spacing.
///
/// Interior rows: `s[i-1] + 4 s[i] + s[i+1] = 3 (m[i-1] + m[i])` with m the secant slopes; the
/// end rows come from equal third derivatives across the first and last interior nodes:
/// s0 + 2 s1 = (5 m0 + m1)/2 and 2 s[n-2] + s[n-1] = (m[n-3] + 5 m[n-2])/2. Tridiagonal, solved
/// by elimination without pivoting (the pivots stay ≥ 0.4 for every n).
pub fn not_a_knot_slopes(y: &[f64], s: &mut [f64]) {
    let n = y.len();
    debug_assert_eq!(s.len(), n);
    if n < 4 {
        // Too few nodes for not-a-knot: the interpolating polynomial's slopes are close enough.
        catmull_rom_slopes(y, s);
        return;
    }
    let m = |i: usize| y[i + 1] - y[i];
    // Forward sweep storing the modified super-diagonal in `c` and rhs in `s`.
    let mut c = vec![0.0f64; n];
    let (b0, c0) = (1.0, 2.0);
    c[0] = c0 / b0;
    s[0] = (2.5 * m(0) + 0.5 * m(1)) / b0;
    for i in 1..n - 1 {
        let (a, b, cc) = (1.0, 4.0, 1.0);
        let d = 3.0 * (m(i - 1) + m(i));
        let piv = b - a * c[i - 1];
        c[i] = cc / piv;
        s[i] = (d - a * s[i - 1]) / piv;
    }
    let (a, b) = (2.0, 1.0);
    let d = 0.5 * m(n - 3) + 2.5 * m(n - 2);
    let piv = b - a * c[n - 2];
    s[n - 1] = (d - a * s[n - 2]) / piv;
    for i in (0..n - 1).rev() {
        s[i] -= c[i] * s[i + 1];
    }
}

fn catmull_rom_slopes(y: &[f64], s: &mut [f64]) {
    let n = y.len();
    if n < 2 {
        s.fill(0.0);
        return;
    }
    s[0] = y[1] - y[0];
    s[n - 1] = y[n - 1] - y[n - 2];
    for i in 1..n - 1 {
        s[i] = 0.5 * (y[i + 1] - y[i - 1]);
    }
}

/// Where one output coordinate falls on the node axis: interval start and Hermite weights.
#[derive(Debug, Clone, Copy)]
pub struct Tap {
    pub i0: usize,
    pub w: [f64; 4],
}

impl Tap {
    /// Tap at fractional index `u` on an axis of `n` nodes (u is clamped to the axis).
    pub fn at(method: Interp, u: f64, n: usize) -> Tap {
        let u = u.clamp(0.0, (n - 1) as f64);
        let i0 = (u.floor() as usize).min(n - 2);
        Tap {
            i0,
            w: method.weights(u - i0 as f64),
        }
    }

    #[inline]
    pub fn eval(&self, y: &[f64], s: &[f64]) -> f64 {
        let i = self.i0;
        self.w[0] * y[i] + self.w[1] * y[i + 1] + self.w[2] * s[i] + self.w[3] * s[i + 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_reproduces_cubics_exactly() {
        // Not-a-knot reproduces any cubic polynomial, ends included.
        let f = |x: f64| 0.3 * x * x * x - 2.0 * x * x + x - 5.0;
        let df = |x: f64| 0.9 * x * x - 4.0 * x + 1.0;
        let y: Vec<f64> = (0..12).map(|i| f(i as f64)).collect();
        let mut s = vec![0.0; y.len()];
        not_a_knot_slopes(&y, &mut s);
        for (i, si) in s.iter().enumerate() {
            assert!((si - df(i as f64)).abs() < 1e-9, "slope {i}: {si}");
        }
        let tap = Tap::at(Interp::Spline, 7.3, y.len());
        assert!((tap.eval(&y, &s) - f(7.3)).abs() < 1e-9);
    }

    #[test]
    fn every_method_interpolates_the_nodes() {
        let y = [3.0, -1.0, 4.0, 1.0, 5.0, 9.0, 2.0];
        for m in Interp::ALL {
            let mut s = [0.0; 7];
            m.slopes(&y, &mut s);
            for (i, yi) in y.iter().enumerate() {
                let v = Tap::at(m, i as f64, y.len()).eval(&y, &s);
                assert!((v - yi).abs() < 1e-12, "{m} at {i}: {v}");
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for m in Interp::ALL {
            assert_eq!(m.name().parse::<Interp>().unwrap(), m);
        }
        assert!("cubic".parse::<Interp>().is_err());
    }
}

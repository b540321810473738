//! The host's camera, as a host has it (view and projection matrices over a local frame tied to
//! the globe by a geodetic anchor, a depth convention, near and far), checked and turned into
//! Stratus' own [`Camera`] and the depth stage's constants.

use glam::camera::rh::{proj::directx, view::look_at_mat4};
use glam::{DVec3, DVec4, Mat4, Vec3};

use super::EmbedError;
use crate::render::camera::{ecef, enu_basis, Camera, EARTH_R};

/// Where the host's world origin is on the globe: the host's world is the tangent frame there,
/// in metres, **x east, y up, z south** (right-handed, y up: `glam`'s `look_at_rh` world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoAnchor {
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Altitude of the origin above sea level (m).
    pub alt_m: f64,
}

/// How the host's depth buffer maps distance to depth (both with wgpu's 0..1 clip depth).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthConvention {
    /// 0 at the near plane, 1 at the far plane (cleared to 1).
    Standard,
    /// 1 at the near plane, 0 at the far plane or at infinity (cleared to 0): the precise one
    /// at flight-simulator distances.
    ReversedZ,
}

/// The host's camera for one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostCamera {
    pub anchor: GeoAnchor,
    /// Host world → view: a rigid transform; the camera looks down −Z with +Y up (right-handed).
    pub view: Mat4,
    /// View → clip: a symmetric perspective with wgpu's 0..1 depth, as the host draws with.
    pub projection: Mat4,
    pub near_m: f32,
    /// `f32::INFINITY` for an infinite reversed-Z projection.
    pub far_m: f32,
    pub depth: DepthConvention,
}

/// What the depth stage needs of the camera: `1/z = inv_a + inv_b·depth`, the depth of nothing
/// drawn, and the projection's focal terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct DepthModel {
    pub inv_a: f32,
    pub inv_b: f32,
    pub none_depth: f32,
    pub fx: f32,
    pub fy: f32,
}

impl HostCamera {
    /// A camera at `eye` looking at `target` (host world, m), with matrices made the way a host
    /// would (`glam::camera::rh`: `look_at_mat4`, the WebGPU/DirectX perspective or its reversed forms).
    #[allow(clippy::too_many_arguments)]
    pub fn look_at(
        anchor: GeoAnchor,
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y_deg: f32,
        aspect: f32,
        (near_m, far_m): (f32, f32),
        depth: DepthConvention,
    ) -> HostCamera {
        let fov = fov_y_deg.to_radians();
        let projection = match depth {
            DepthConvention::Standard => directx::perspective(fov, aspect, near_m, far_m),
            DepthConvention::ReversedZ if far_m.is_infinite() => {
                directx::perspective_infinite_reverse(fov, aspect, near_m)
            }
            DepthConvention::ReversedZ => directx::perspective(fov, aspect, far_m, near_m),
        };
        HostCamera {
            anchor,
            view: look_at_mat4(eye, target, up),
            projection,
            near_m,
            far_m,
            depth,
        }
    }

    /// Projection × view: what the host draws its geometry with.
    pub fn view_projection(&self) -> Mat4 {
        self.projection * self.view
    }

    /// Stratus' camera for a `width`×`height` target, after checking that the matrices are
    /// finite, the view rigid, the projection a symmetric perspective of the target's aspect,
    /// and near/far what the projection says for the convention.
    pub fn to_stratus(&self, width: u32, height: u32) -> Result<Camera, EmbedError> {
        let focal = self.check_projection(width, height)?;
        let v = self.view.as_dmat4();
        if !v.is_finite() {
            return Err(EmbedError::BadCamera(
                "the view matrix is not finite".into(),
            ));
        }
        let iv = v.inverse();
        let axis = |c: DVec4| c.truncate();
        let (right, up, back) = (axis(iv.x_axis), axis(iv.y_axis), axis(iv.z_axis));
        let rigid = [right.length(), up.length(), back.length()]
            .iter()
            .all(|l| (l - 1.0).abs() < 1e-4)
            && right.dot(up).abs() < 1e-4
            && right.cross(up).dot(back) > 0.999;
        if !iv.is_finite() || !rigid {
            return Err(EmbedError::BadCamera(
                "the view matrix is not a rigid transform (rotation and translation)".into(),
            ));
        }
        let a = &self.anchor;
        if !(a.lat_deg.is_finite() && a.lon_deg.is_finite() && a.alt_m.is_finite()) {
            return Err(EmbedError::BadCamera("the anchor is not finite".into()));
        }
        // Host world (x east, y up, z south) → ECEF at the anchor.
        let (e, n, u) = enu_basis(a.lat_deg, a.lon_deg);
        let to_ecef = |w: DVec3| e * w.x - n * w.z + u * w.y;
        let pos = ecef(a.lat_deg, a.lon_deg, a.alt_m) + to_ecef(axis(iv.w_axis));
        let (forward, right) = (to_ecef(-back).normalize(), to_ecef(right).normalize());
        let r = pos.length();
        let lat_deg = (pos.z / r).clamp(-1.0, 1.0).asin().to_degrees();
        let lon_deg = pos.y.atan2(pos.x).to_degrees();
        let (ce, cn, cu) = enu_basis(lat_deg, lon_deg);
        let mut cam = Camera {
            lat_deg,
            lon_deg,
            alt_m: r - EARTH_R,
            forward_enu: DVec3::new(forward.dot(ce), forward.dot(cn), forward.dot(cu)),
            fov_deg: (2.0 * (1.0 / focal.1).atan()).to_degrees(),
            roll_deg: 0.0,
        };
        // The bank that turns Stratus' level right vector into the host's (camera::Basis).
        let level = cam.basis();
        let (cr, sr) = (right.dot(level.right), -right.dot(level.view_up));
        cam.roll_deg = sr.atan2(cr).to_degrees();
        cam.validate()
            .map_err(|e| EmbedError::BadCamera(e.to_string()))?;
        Ok(cam)
    }

    /// The projection in f64 and its focal terms (fx, fy), refused unless a symmetric
    /// perspective of the target's aspect whose depth agrees with near, far and the convention.
    fn check_projection(&self, width: u32, height: u32) -> Result<(f64, f64), EmbedError> {
        let bad = |m: String| Err(EmbedError::Projection(m));
        let p = self.projection.as_dmat4();
        if !p.is_finite() {
            return Err(EmbedError::BadCamera(
                "the projection matrix is not finite".into(),
            ));
        }
        let (fx, fy) = (p.x_axis.x, p.y_axis.y);
        let perspective = p.z_axis.w == -1.0 && p.x_axis.w == 0.0 && p.y_axis.w == 0.0;
        let symmetric = p.z_axis.x.abs() < 1e-6
            && p.z_axis.y.abs() < 1e-6
            && p.x_axis.y == 0.0
            && p.y_axis.x == 0.0;
        if !(perspective && symmetric && fx > 0.0 && fy > 0.0) {
            return bad("not a symmetric right-handed perspective (an off-centre, orthographic or skewed projection is not supported)".into());
        }
        let aspect = width as f64 / height as f64;
        if ((fy / fx) - aspect).abs() > 1e-3 * aspect {
            return bad(format!(
                "its aspect {:.4} is not the target's {width}×{height} ({aspect:.4})",
                fy / fx
            ));
        }
        let (near, far) = (self.near_m as f64, self.far_m as f64);
        if !(near.is_finite() && near > 0.0 && far > near) {
            return bad(format!(
                "near {near} m and far {far} m must satisfy 0 < near < far"
            ));
        }
        if far.is_infinite() && self.depth == DepthConvention::Standard {
            return bad("an infinite far plane needs reversed-Z".into());
        }
        let depth_at = |z: f64| {
            let c = p * DVec4::new(0.0, 0.0, -z, 1.0);
            c.z / c.w
        };
        let (at_near, at_far) = match self.depth {
            DepthConvention::Standard => (0.0, 1.0),
            DepthConvention::ReversedZ => (1.0, 0.0),
        };
        let off_near = (depth_at(near) - at_near).abs();
        let off_far = if far.is_finite() {
            (depth_at(far) - at_far).abs()
        } else {
            0.0
        };
        if off_near > 1e-3 || off_far > 1e-3 {
            return bad(format!(
                "with {:?} depth, near {near} m should map to {at_near} and far {far} m to {at_far}; the projection maps them to {:.4} and {:.4}",
                self.depth,
                depth_at(near),
                if far.is_finite() { depth_at(far) } else { at_far }
            ));
        }
        Ok((fx, fy))
    }

    /// The depth stage's constants (after [`HostCamera::to_stratus`] accepted the camera).
    pub(super) fn depth_model(&self) -> DepthModel {
        let (n, f) = (self.near_m as f64, self.far_m as f64);
        let inv_f = if f.is_finite() { 1.0 / f } else { 0.0 };
        let span = 1.0 / n - inv_f;
        let (inv_a, inv_b, none_depth) = match self.depth {
            DepthConvention::Standard => (1.0 / n, -span, 1.0),
            DepthConvention::ReversedZ => (inv_f, span, 0.0),
        };
        DepthModel {
            inv_a: inv_a as f32,
            inv_b: inv_b as f32,
            none_depth,
            fx: self.projection.x_axis.x,
            fy: self.projection.y_axis.y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ANCHOR: GeoAnchor = GeoAnchor {
        lat_deg: 47.0,
        lon_deg: 8.0,
        alt_m: 400.0,
    };

    fn cam(eye: Vec3, target: Vec3, up: Vec3, depth: DepthConvention) -> HostCamera {
        let far = if depth == DepthConvention::ReversedZ {
            f32::INFINITY
        } else {
            50_000.0
        };
        HostCamera::look_at(ANCHOR, eye, target, up, 50.0, 1.5, (0.5, far), depth)
    }

    /// Stratus' camera reproduces the host's rays: a world point the host sees at the centre
    /// and one it sees up and to the right are where Stratus projects them.
    #[test]
    fn stratus_sees_what_the_host_sees() {
        let tilted = Vec3::new(0.3, 1.0, 0.1).normalize();
        for (eye, target, up) in [
            (
                Vec3::new(0.0, 1500.0, 0.0),
                Vec3::new(3000.0, 1000.0, -4000.0),
                Vec3::Y,
            ),
            (
                Vec3::new(-200.0, 3000.0, 500.0),
                Vec3::new(-200.0, 0.0, 500.1),
                Vec3::Y,
            ),
            (
                Vec3::new(10.0, 800.0, 0.0),
                Vec3::new(0.0, 900.0, -5000.0),
                tilted,
            ),
        ] {
            for depth in [DepthConvention::Standard, DepthConvention::ReversedZ] {
                let h = cam(eye, target, up, depth);
                let c = h.to_stratus(300, 200).expect("a valid camera");
                let (e, n, u) = enu_basis(ANCHOR.lat_deg, ANCHOR.lon_deg);
                let origin = ecef(ANCHOR.lat_deg, ANCHOR.lon_deg, ANCHOR.alt_m);
                let world = |w: Vec3| {
                    let w = w.as_dvec3();
                    origin + e * w.x - n * w.z + u * w.y
                };
                // A point in view space (x right, y up, −z ahead) → host world → ECEF.
                let iv = h.view.inverse();
                for (vx, vy, want) in [(0.0, 0.0, (150.0, 100.0)), (0.2, 0.1, (0.0, 0.0))] {
                    let vp = Vec3::new(vx * 1000.0, vy * 1000.0, -1000.0);
                    let clip = h.projection * vp.extend(1.0);
                    let ndc = clip.truncate() / clip.w;
                    let px = ((ndc.x as f64 + 1.0) * 150.0, (1.0 - ndc.y as f64) * 100.0);
                    let want = if want.0 == 0.0 { px } else { want };
                    let got = c
                        .project(world(iv.transform_point3(vp)), 300, 200)
                        .expect("in front");
                    assert!(
                        (got.0 - want.0).abs() < 0.05 && (got.1 - want.1).abs() < 0.05,
                        "{eye} {target}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn depth_model_inverts_the_projection() {
        for depth in [DepthConvention::Standard, DepthConvention::ReversedZ] {
            let h = cam(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, depth);
            let m = h.depth_model();
            for z in [1.0f32, 37.0, 2500.0, 20_000.0] {
                let c = h.projection * Vec3::new(0.0, 0.0, -z).extend(1.0);
                let d = c.z / c.w;
                let back = 1.0 / (m.inv_a + m.inv_b * d);
                // Standard depth near 1 has f32's ulp (6·10⁻⁸): z·z/near of that in metres, the
                // precision reversed-Z is for (0.5 m near: 48 m at 20 km).
                let ulp = if depth == DepthConvention::Standard {
                    z * z / 0.5 * 6e-8
                } else {
                    0.0
                };
                assert!(
                    (back - z).abs() < 1e-3 * z + 2.0 * ulp,
                    "{depth:?}: {z} → {d} → {back}"
                );
            }
        }
    }

    #[test]
    fn misuse_is_refused() {
        let good = cam(
            Vec3::new(0.0, 100.0, 0.0),
            Vec3::NEG_Z,
            Vec3::Y,
            DepthConvention::Standard,
        );
        let mut nan = good;
        nan.view.x_axis.x = f32::NAN;
        assert!(matches!(
            nan.to_stratus(300, 200),
            Err(EmbedError::BadCamera(_))
        ));
        // The target's aspect is not the projection's.
        assert!(matches!(
            good.to_stratus(200, 200),
            Err(EmbedError::Projection(_))
        ));
        // Reversed-Z matrices called standard.
        let mut swapped = good;
        swapped.depth = DepthConvention::ReversedZ;
        assert!(matches!(
            swapped.to_stratus(300, 200),
            Err(EmbedError::Projection(_))
        ));
        // A scaled view.
        let mut scaled = good;
        scaled.view *= Mat4::from_scale(Vec3::splat(2.0));
        assert!(matches!(
            scaled.to_stratus(300, 200),
            Err(EmbedError::BadCamera(_))
        ));
        // Below the sea.
        let deep = cam(
            Vec3::new(0.0, -900.0, 0.0),
            Vec3::NEG_Z,
            Vec3::Y,
            DepthConvention::Standard,
        );
        assert!(matches!(
            deep.to_stratus(300, 200),
            Err(EmbedError::BadCamera(_))
        ));
    }
}

//! Where the viewer is and where it looks: a perspective camera on the globe, or the top-down
//! orthographic view of a region used for scoring. All geometry here is f64; the GPU only ever
//! sees directions and camera-relative quantities (DESIGN §4: f32 at 6.4·10⁶ m is 0.5 m).

use glam::DVec3;

use super::RenderError;
use crate::sun::up_at;

/// Mean Earth radius the renderer's sphere uses (m).
pub const EARTH_R: f64 = 6_371_000.0;

/// Highest camera the renderer accepts (m): far beyond any layer, still inside f32's comfort.
pub const MAX_ALTITUDE_M: f64 = 1.0e7;

/// A perspective camera: position on the sphere and a view direction in local east/north/up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
    /// View direction in the local east, north, up frame (need not be unit length, must not be 0).
    pub forward_enu: DVec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Bank angle, degrees (positive rolls the view clockwise, right wing down).
    pub roll_deg: f64,
}

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum View {
    Perspective(Camera),
    /// The map's region straight down, one nadir ray per output pixel (DESIGN §5).
    TopDown,
}

/// East, north, up unit vectors (ECEF) at a latitude/longitude.
pub fn enu_basis(lat_deg: f64, lon_deg: f64) -> (DVec3, DVec3, DVec3) {
    let (la, lo) = (lat_deg.to_radians(), lon_deg.to_radians());
    let east = DVec3::new(-lo.sin(), lo.cos(), 0.0);
    let north = DVec3::new(-la.sin() * lo.cos(), -la.sin() * lo.sin(), la.cos());
    (east, north, up_at(lat_deg, lon_deg))
}

/// ENU components of a heading (degrees clockwise from north) and pitch (degrees up).
pub fn heading_pitch_enu(heading_deg: f64, pitch_deg: f64) -> DVec3 {
    let (h, p) = (heading_deg.to_radians(), pitch_deg.to_radians());
    DVec3::new(p.cos() * h.sin(), p.cos() * h.cos(), p.sin())
}

/// The ECEF frame a camera renders with.
#[derive(Clone, Copy, Debug)]
pub struct Basis {
    pub position: DVec3,
    pub up: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub view_up: DVec3,
}

impl Camera {
    /// A camera from heading/pitch in degrees.
    pub fn new(lat_deg: f64, lon_deg: f64, alt_m: f64, heading_deg: f64, pitch_deg: f64) -> Camera {
        Camera {
            lat_deg,
            lon_deg,
            alt_m,
            forward_enu: heading_pitch_enu(heading_deg, pitch_deg),
            fov_deg: 60.0,
            roll_deg: 0.0,
        }
    }

    /// Reject what cannot be rendered: below the ground, non-finite, no view direction, bad fov.
    pub fn validate(&self) -> Result<(), RenderError> {
        use stratus_ingest::meta::show_num;
        let bad = |m: String| Err(RenderError::BadCamera(m));
        if !(self.lat_deg.is_finite() && self.lon_deg.is_finite() && self.alt_m.is_finite()) {
            return bad("position is not a finite number".into());
        }
        if !(-90.0..=90.0).contains(&self.lat_deg) {
            return bad(format!(
                "latitude {} is outside -90..90",
                show_num(self.lat_deg)
            ));
        }
        if self.alt_m < 0.0 {
            return bad(format!(
                "altitude {} m is below the ground (sea level is 0)",
                show_num(self.alt_m)
            ));
        }
        if self.alt_m > MAX_ALTITUDE_M {
            return bad(format!(
                "altitude {} m is above the {} m limit",
                show_num(self.alt_m),
                show_num(MAX_ALTITUDE_M)
            ));
        }
        let len = self.forward_enu.length();
        if !len.is_finite() || len < 1e-9 {
            return bad("view direction has zero length".into());
        }
        if !self.roll_deg.is_finite() {
            return bad("roll is not a finite number".into());
        }
        if !(self.fov_deg > 0.5 && self.fov_deg < 170.0) {
            return bad(format!(
                "field of view {}° is outside 0.5..170",
                show_num(self.fov_deg)
            ));
        }
        Ok(())
    }

    /// The ECEF frame; straight up or down keeps a stable right vector (from the heading).
    pub fn basis(&self) -> Basis {
        let (east, north, up) = enu_basis(self.lat_deg, self.lon_deg);
        let f = self.forward_enu.normalize();
        let forward = (east * f.x + north * f.y + up * f.z).normalize();
        let horiz = DVec3::new(f.x, f.y, 0.0);
        // Right of the horizontal heading; looking straight up/down the heading is north.
        let right = if horiz.length() > 1e-9 {
            let h = horiz.normalize();
            (east * h.y - north * h.x).normalize()
        } else {
            east
        };
        let view_up = right.cross(forward).normalize();
        // Bank: turn right and up about the forward axis.
        let (sr, cr) = self.roll_deg.to_radians().sin_cos();
        let (right, view_up) = (right * cr - view_up * sr, view_up * cr + right * sr);
        Basis {
            position: up * (EARTH_R + self.alt_m),
            up,
            forward,
            right,
            view_up,
        }
    }

    /// Unit ECEF direction through pixel position (x right, y down, continuous; a pixel's
    /// centre is +0.5): the inverse of [`Camera::project`], and the march's `persp_dir`.
    pub fn pixel_ray(&self, x: f64, y: f64, width: u32, height: u32) -> DVec3 {
        let b = self.basis();
        let tn = (self.fov_deg.to_radians() * 0.5).tan();
        let aspect = f64::from(width) / f64::from(height);
        let sx = (2.0 * x / f64::from(width) - 1.0) * tn * aspect;
        let sy = (1.0 - 2.0 * y / f64::from(height)) * tn;
        (b.forward + b.right * sx + b.view_up * sy).normalize()
    }

    /// Pixel (x right, y down, continuous) where an ECEF point appears, or None behind the camera.
    pub fn project(&self, point: DVec3, width: u32, height: u32) -> Option<(f64, f64)> {
        let b = self.basis();
        let v = point - b.position;
        let z = v.dot(b.forward);
        if z <= 0.0 {
            return None;
        }
        let tn = (self.fov_deg.to_radians() * 0.5).tan();
        let aspect = width as f64 / height as f64;
        let x = v.dot(b.right) / z / (tn * aspect);
        let y = v.dot(b.view_up) / z / tn;
        Some((
            (x + 1.0) * 0.5 * width as f64,
            (1.0 - y) * 0.5 * height as f64,
        ))
    }
}

/// ECEF point at latitude/longitude/altitude on the renderer's sphere.
pub fn ecef(lat_deg: f64, lon_deg: f64, alt_m: f64) -> DVec3 {
    up_at(lat_deg, lon_deg) * (EARTH_R + alt_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_ray_is_the_inverse_of_project() {
        let mut cam = Camera::new(35.0, 120.0, 9000.0, 40.0, -25.0);
        cam.roll_deg = 12.0;
        let b = cam.basis();
        for (x, y) in [(0.5, 0.5), (160.0, 90.0), (300.25, 17.75), (319.5, 179.5)] {
            let p = b.position + cam.pixel_ray(x, y, 320, 180) * 50_000.0;
            let (px, py) = cam.project(p, 320, 180).expect("in front of the camera");
            assert!(
                (px - x).abs() < 1e-6 && (py - y).abs() < 1e-6,
                "({x}, {y}) -> ({px}, {py})"
            );
        }
    }

    #[test]
    fn basis_is_orthonormal_even_looking_straight_down() {
        for pitch in [-90.0, -30.0, 0.0, 45.0, 90.0] {
            let b = Camera::new(35.0, 120.0, 5000.0, 30.0, pitch).basis();
            assert!((b.forward.length() - 1.0).abs() < 1e-12);
            assert!(b.forward.dot(b.right).abs() < 1e-12, "{pitch}");
            assert!(b.forward.dot(b.view_up).abs() < 1e-12, "{pitch}");
        }
    }

    #[test]
    fn project_puts_the_look_at_point_in_the_centre() {
        let cam = Camera::new(10.0, 20.0, 3000.0, 90.0, -20.0);
        let b = cam.basis();
        let (x, y) = cam
            .project(b.position + b.forward * 5000.0, 800, 600)
            .unwrap();
        assert!((x - 400.0).abs() < 1e-6 && (y - 300.0).abs() < 1e-6);
        // Heading 90 looks east: a point to the north is on the left.
        let (e, n, _) = enu_basis(10.0, 20.0);
        let (xl, _) = cam
            .project(b.position + e * 5000.0 + n * 1000.0, 800, 600)
            .unwrap();
        assert!(xl < 400.0);
    }

    #[test]
    fn bad_cameras_are_refused() {
        assert!(Camera::new(0.0, 0.0, -1.0, 0.0, 0.0).validate().is_err());
        let mut c = Camera::new(0.0, 0.0, 10.0, 0.0, 0.0);
        c.forward_enu = DVec3::ZERO;
        assert!(c.validate().is_err());
        assert!(Camera::new(0.0, 0.0, 0.0, 0.0, 90.0).validate().is_ok());
    }
}

//! The coverage formula (paper eq. 1–2): what a pixel's relative humidity means as cloud.

/// Paper eq. 1–2: coverage from relative humidity (fractions).
#[inline]
pub fn coverage(rh: f64, rh_cr: f64) -> f64 {
    let c = ((rh - rh_cr) / (1.0 - rh_cr)).clamp(0.0, 1.0);
    c * c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layer::validate_rh_cr;

    #[test]
    fn coverage_formula_at_its_edges() {
        assert_eq!(coverage(0.65, 0.65), 0.0);
        assert_eq!(coverage(0.0, 0.65), 0.0);
        assert_eq!(coverage(1.0, 0.65), 1.0);
        assert!((coverage(0.825, 0.65) - 0.25).abs() < 1e-12);
        assert_eq!(coverage(0.5, 0.0), 0.25);
        assert!(coverage(0.99995, 0.9999).is_finite());
        assert!(validate_rh_cr(1.0).is_err());
        assert!(validate_rh_cr(1.5).is_err());
        assert!(validate_rh_cr(f64::NAN).is_err());
        assert!(validate_rh_cr(-0.1).is_err());
        assert_eq!(validate_rh_cr(0.0).unwrap(), 0.0);
    }
}

//! The flight volume: the box the receiver physically moves in. A state
//! outside it is not a position but a symptom (a mirror solution of the
//! range differences, a filter dragged off by outliers), so filters are
//! projected back into it and a state that keeps leaving counts as lost.

use nalgebra::Vector3;

/// Why a volume cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// No transmitter to take the box from.
    #[error("no transmitter to bound the volume")]
    NoTransmitters,
    /// A corner or the margin is not finite, or the box is empty.
    #[error("the volume's corners must be finite with min < max on every axis")]
    Empty,
}

/// An axis-aligned box, metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FlightVolume {
    /// Lower corner, metres.
    pub min_m: [f64; 3],
    /// Upper corner, metres.
    pub max_m: [f64; 3],
}

impl FlightVolume {
    /// A box from its corners; every `min < max`, all finite.
    pub fn new(min_m: [f64; 3], max_m: [f64; 3]) -> Result<Self, VolumeError> {
        let ok =
            (0..3).all(|k| min_m[k].is_finite() && max_m[k].is_finite() && min_m[k] < max_m[k]);
        if ok {
            Ok(Self { min_m, max_m })
        } else {
            Err(VolumeError::Empty)
        }
    }

    /// The bounding box of the transmitters grown by `margin_m` on every
    /// side: anchors sit on the walls, floor and ceiling of the room the
    /// receiver moves in, so the receiver stays within a margin of their
    /// box.
    pub fn around(transmitters_m: &[[f64; 3]], margin_m: f64) -> Result<Self, VolumeError> {
        if transmitters_m.is_empty() {
            return Err(VolumeError::NoTransmitters);
        }
        if !(margin_m.is_finite() && margin_m >= 0.0) {
            return Err(VolumeError::Empty);
        }
        let mut min_m = [f64::INFINITY; 3];
        let mut max_m = [f64::NEG_INFINITY; 3];
        for t in transmitters_m {
            for k in 0..3 {
                min_m[k] = min_m[k].min(t[k] - margin_m);
                max_m[k] = max_m[k].max(t[k] + margin_m);
            }
        }
        Self::new(min_m, max_m)
    }

    /// Whether `p` is inside (bounds included).
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|k| self.min_m[k] <= p[k] && p[k] <= self.max_m[k])
    }

    /// The nearest point of the box to `p`, and which axes were moved.
    pub fn clamp(&self, p: &Vector3<f64>) -> (Vector3<f64>, [bool; 3]) {
        let mut moved = [false; 3];
        let mut q = *p;
        for k in 0..3 {
            let c = p[k].clamp(self.min_m[k], self.max_m[k]);
            moved[k] = c != p[k];
            q[k] = c;
        }
        (q, moved)
    }

    /// Distance from `p` to the box, metres (0 inside).
    pub fn outside_by_m(&self, p: &Vector3<f64>) -> f64 {
        (self.clamp(p).0 - p).norm()
    }

    /// The centre of the box.
    pub fn centre_m(&self) -> Vector3<f64> {
        Vector3::from(std::array::from_fn(|k| {
            0.5 * (self.min_m[k] + self.max_m[k])
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_around_transmitters_has_the_margin_and_clamps_outside_points() {
        let v = FlightVolume::around(&[[0.0, 0.0, 0.2], [6.0, 4.0, 2.8]], 0.5).unwrap();
        assert_eq!(v.min_m, [-0.5, -0.5, -0.3]);
        assert_eq!(v.max_m, [6.5, 4.5, 3.3]);
        assert!(v.contains(&Vector3::new(3.0, 2.0, 1.0)));
        let below = Vector3::new(3.0, 2.0, -10.0);
        let (q, moved) = v.clamp(&below);
        assert_eq!(q, Vector3::new(3.0, 2.0, -0.3));
        assert_eq!(moved, [false, false, true]);
        assert!((v.outside_by_m(&below) - 9.7).abs() < 1e-12);
    }

    #[test]
    fn empty_or_non_finite_boxes_are_refused() {
        assert_eq!(
            FlightVolume::around(&[], 0.5),
            Err(VolumeError::NoTransmitters)
        );
        assert_eq!(
            FlightVolume::new([0.0; 3], [1.0, 0.0, 1.0]),
            Err(VolumeError::Empty)
        );
        assert_eq!(
            FlightVolume::around(&[[0.0; 3]], f64::NAN),
            Err(VolumeError::Empty)
        );
    }
}

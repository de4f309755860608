//! [`Supersample`]: how finely a pixel or a voxel is sampled, one meaning everywhere.
//!
//! A pixel (or voxel) is split into `k` equal strata along each of its edges and sampled at the
//! strata's centres: offsets `(a + ½)/k`, `a = 0 … k−1`, from its lower corner. A picture's pixel
//! therefore gets `k × k` samples ([`Supersample::per_pixel`]), a voxel `k³`
//! ([`Supersample::per_voxel`]). Renderers whose rows are independent (images with parallax
//! warp each screen row from one view row) take the `k` samples across the pixel only: the `k`
//! rows of a pixel's `k × k` samples would read the same data.

use serde::{Deserialize, Serialize};

/// Sub-samples per pixel (or voxel) edge, `k ≥ 1` (module docs): `k × k` per pixel, `k³` per
/// voxel, at the strata's centres. Serialised as the plain number `k`; `0` is refused when read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "usize", into = "usize")]
pub struct Supersample(usize);

impl Supersample {
    /// One sample per pixel, at its centre.
    pub const ONE: Self = Self(1);

    /// `k` sub-samples per edge; `None` for `k = 0`.
    pub const fn new(k: usize) -> Option<Self> {
        if k == 0 { None } else { Some(Self(k)) }
    }

    /// `k` sub-samples per edge, for constants written in code (`Supersample::of(3)`).
    ///
    /// # Panics
    /// If `k = 0` (at compile time where used in a constant); input goes through [`new`](Self::new)
    /// or serde, which refuse it with an error.
    pub const fn of(k: usize) -> Self {
        match Self::new(k) {
            Some(s) => s,
            None => panic!("a supersample count is at least 1"),
        }
    }

    /// Sub-samples per edge, `k`.
    pub const fn get(self) -> usize {
        self.0
    }

    /// Samples per pixel, `k²`.
    pub const fn per_pixel(self) -> usize {
        self.0 * self.0
    }

    /// Samples per voxel, `k³`.
    pub const fn per_voxel(self) -> usize {
        self.0 * self.0 * self.0
    }

    /// Offset of stratum `a` (`0 ≤ a < k`) from the pixel's lower edge, in pixels: `(a + ½)/k`.
    pub fn offset(self, a: usize) -> f64 {
        (a as f64 + 0.5) / self.0 as f64
    }
}

impl Default for Supersample {
    /// [`Supersample::ONE`].
    fn default() -> Self {
        Self::ONE
    }
}

impl std::fmt::Display for Supersample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl TryFrom<usize> for Supersample {
    type Error = String;

    fn try_from(k: usize) -> Result<Self, String> {
        Self::new(k).ok_or_else(|| {
            "supersample = 0: at least 1 sub-sample per pixel or voxel edge is needed".to_string()
        })
    }
}

impl From<Supersample> for usize {
    fn from(s: Supersample) -> usize {
        s.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_is_refused_and_counts_follow_k() {
        assert_eq!(Supersample::new(0), None);
        let k = Supersample::of(3);
        assert_eq!((k.get(), k.per_pixel(), k.per_voxel()), (3, 9, 27));
        assert_eq!(k.offset(0), 0.5 / 3.0);
        assert_eq!(k.offset(2), 2.5 / 3.0);
        let read: Result<Supersample, _> = serde_json::from_str("0");
        assert!(read.unwrap_err().to_string().contains("at least 1"));
        assert_eq!(serde_json::to_string(&k).unwrap(), "3");
        assert_eq!(serde_json::from_str::<Supersample>("3").unwrap(), k);
    }
}

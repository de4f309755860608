//! Where a mesh came from: its up axis, and the exact affine map from the source's coordinates to
//! altrep's normalised frame (crate docs: `y` up, inside the bounding cylinder), so that a renderer
//! can draw every stand-in where the mesh was.
//!
//! The map is `p_n = s·U·p + t`: `U` is the proper rotation that takes the source's up axis to `+y`
//! ([`UpAxis::rotation`]), `s > 0` the uniform scale of the normalisation, `t` its translation. The
//! vertices altrep traces are this map's image rounded to `f32` (relative error about `6·10⁻⁸` of the
//! object's size).

use std::str::FromStr;

use glam::{DAffine3, DMat3, DVec3};

/// Which source axis points up. glTF is `+y` by definition; OBJ has no convention and defaults to
/// `+y`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum UpAxis {
    /// `+x` is up.
    #[serde(rename = "x")]
    PosX,
    /// `−x` is up.
    #[serde(rename = "-x")]
    NegX,
    /// `+y` is up (no rotation).
    #[default]
    #[serde(rename = "y")]
    PosY,
    /// `−y` is up.
    #[serde(rename = "-y")]
    NegY,
    /// `+z` is up (Blender's and many CAD tools' convention).
    #[serde(rename = "z")]
    PosZ,
    /// `−z` is up.
    #[serde(rename = "-z")]
    NegZ,
}

impl UpAxis {
    /// Every axis, in the order of its names.
    pub const ALL: [UpAxis; 6] = [
        UpAxis::PosX,
        UpAxis::NegX,
        UpAxis::PosY,
        UpAxis::NegY,
        UpAxis::PosZ,
        UpAxis::NegZ,
    ];

    /// The name used in manifests and on the command line: `x`, `-x`, `y`, `-y`, `z`, `-z`.
    pub fn name(self) -> &'static str {
        match self {
            UpAxis::PosX => "x",
            UpAxis::NegX => "-x",
            UpAxis::PosY => "y",
            UpAxis::NegY => "-y",
            UpAxis::PosZ => "z",
            UpAxis::NegZ => "-z",
        }
    }

    /// The proper rotation (determinant +1, entries 0 and ±1) taking this axis to `+y`:
    /// `z` up maps `(x, y, z) → (x, z, −y)`, `x` up maps `(x, y, z) → (−y, x, z)`, and so on.
    pub fn rotation(self) -> DMat3 {
        // Rows of the matrix, so that `U·p` reads as the map above.
        let rows = match self {
            UpAxis::PosY => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            UpAxis::NegY => [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            UpAxis::PosZ => [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
            UpAxis::NegZ => [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            UpAxis::PosX => [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            UpAxis::NegX => [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        };
        DMat3::from_cols_array_2d(&rows).transpose()
    }
}

impl FromStr for UpAxis {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim().trim_start_matches('+');
        Self::ALL
            .into_iter()
            .find(|a| a.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown up axis '{s}' (one of: x, -x, y, -y, z, -z)"))
    }
}

impl std::fmt::Display for UpAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The map from a source's coordinates to the normalised frame, and what the source's units are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Source coordinates → normalised frame (`p_n = s·U·p + t`).
    pub to_normalised: DAffine3,
    /// The source's up axis.
    pub up: UpAxis,
    /// The source's length unit: `"metre"` for glTF (by its specification), `"file unit"` for
    /// OBJ and raw triangles (no unit is declared).
    pub units: &'static str,
}

impl Placement {
    /// The map for rotation `up`, scale `scale` and translation `translation`.
    pub(crate) fn new(up: UpAxis, scale: f64, translation: DVec3, units: &'static str) -> Self {
        Self {
            to_normalised: DAffine3 {
                matrix3: up.rotation() * scale,
                translation,
            },
            up,
            units,
        }
    }

    /// The inverse map: normalised frame → source coordinates.
    pub fn to_source(&self) -> DAffine3 {
        self.to_normalised.inverse()
    }

    /// The uniform scale `s` of the map (normalised units per source unit).
    pub fn scale(&self) -> f64 {
        self.to_normalised.matrix3.x_axis.length()
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_abs_diff_eq;

    use super::*;

    #[test]
    fn every_up_axis_is_a_proper_rotation_taking_it_to_plus_y() {
        let axes = [
            (UpAxis::PosX, DVec3::X),
            (UpAxis::NegX, DVec3::NEG_X),
            (UpAxis::PosY, DVec3::Y),
            (UpAxis::NegY, DVec3::NEG_Y),
            (UpAxis::PosZ, DVec3::Z),
            (UpAxis::NegZ, DVec3::NEG_Z),
        ];
        for (axis, v) in axes {
            let r = axis.rotation();
            assert_abs_diff_eq!(r.determinant(), 1.0);
            assert_eq!(r * v, DVec3::Y, "{axis}");
            assert_eq!(axis.name().parse::<UpAxis>(), Ok(axis));
        }
        assert_eq!(
            UpAxis::PosZ.rotation() * DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 3.0, -2.0)
        );
        assert!("w".parse::<UpAxis>().is_err());
        assert_eq!("+Z".parse::<UpAxis>(), Ok(UpAxis::PosZ));
    }
}

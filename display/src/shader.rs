//! The display's WGSL, composed from one shared prelude (`shaders/common.wgsl`: the precision
//! alias, the full-screen quad, the CPU's diffuse shading, the fragment outputs) and one file per
//! representation. [`compose`] is the only place a shader's source is assembled, and
//! [`variants`] lists every (shader, precision) the display can build, so a test parses and
//! validates each with naga on the CPU, without a device.

/// Arithmetic of a shader's geometry and march.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// `f32` throughout: the production shaders, what an engine ships.
    F32,
    /// Geometry and march in `f64` (needs `SHADER_F64`): the exact twin of the CPU's march.
    F64,
}

/// The shared prelude.
const COMMON: &str = include_str!("shaders/common.wgsl");
/// The line of the prelude that sets the precision of `real`.
const ALIAS_F32: &str = "alias real = f32;";

/// A display shader: its own code, composed after the prelude by [`compose`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shader {
    /// Images with parallax (`shaders/parallax.wgsl`).
    Parallax,
    /// Cylindrical impostors (`shaders/cylinder.wgsl`).
    Cylinder,
    /// Images with parallax from any direction (`shaders/sphere.wgsl`).
    Sphere,
    /// Pyramid lookups on a textured plane (`shaders/pyramid.wgsl`, `f32` only).
    Pyramid,
    /// Slices of an object (`shaders/slices.wgsl`, `f32` only).
    Slices,
    /// The ellipsoid octree (`shaders/octree.wgsl`, `f32` only).
    Octree,
}

impl Shader {
    /// Every shader.
    pub const ALL: [Shader; 6] = [
        Shader::Parallax,
        Shader::Cylinder,
        Shader::Sphere,
        Shader::Pyramid,
        Shader::Slices,
        Shader::Octree,
    ];

    /// The shader's own code (without the prelude).
    fn body(self) -> &'static str {
        match self {
            Shader::Parallax => include_str!("shaders/parallax.wgsl"),
            Shader::Cylinder => include_str!("shaders/cylinder.wgsl"),
            Shader::Sphere => include_str!("shaders/sphere.wgsl"),
            Shader::Pyramid => include_str!("shaders/pyramid.wgsl"),
            Shader::Slices => include_str!("shaders/slices.wgsl"),
            Shader::Octree => include_str!("shaders/octree.wgsl"),
        }
    }

    /// A label for the device's messages, e.g. `parallax.wgsl (f64)`.
    pub fn label(self, precision: Precision) -> String {
        let name = match self {
            Shader::Parallax => "parallax",
            Shader::Cylinder => "cylinder",
            Shader::Sphere => "sphere",
            Shader::Pyramid => "pyramid",
            Shader::Slices => "slices",
            Shader::Octree => "octree",
        };
        let p = match precision {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        };
        format!("{name}.wgsl ({p})")
    }

    /// Whether the fragment stage writes depth (an `FsOut` with a depth target): every opaque
    /// impostor; the pyramid's plane and the translucent volumes (slices, octree) write colour
    /// only.
    pub fn writes_depth(self) -> bool {
        !matches!(self, Shader::Pyramid | Shader::Slices | Shader::Octree)
    }

    /// The precisions the shader exists in.
    pub fn precisions(self) -> &'static [Precision] {
        match self {
            Shader::Pyramid | Shader::Slices | Shader::Octree => &[Precision::F32],
            _ => &[Precision::F32, Precision::F64],
        }
    }
}

/// The complete WGSL of `shader` in `precision`: the prelude with `real` set, then the shader's
/// own code. Cost: one copy of the source (tens of kilobytes).
pub fn compose(shader: Shader, precision: Precision) -> String {
    let prelude = match precision {
        Precision::F32 => COMMON.to_string(),
        Precision::F64 => COMMON.replacen(ALIAS_F32, "alias real = f64;", 1),
    };
    format!("{prelude}\n{}", shader.body())
}

/// Every (shader, precision) the display builds, with its composed source.
pub fn variants() -> Vec<(Shader, Precision, String)> {
    Shader::ALL
        .iter()
        .flat_map(|&s| s.precisions().iter().map(move |&p| (s, p, compose(s, p))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prelude_sets_the_precision_once() {
        assert_eq!(COMMON.matches(ALIAS_F32).count(), 1);
        for s in Shader::ALL {
            assert!(
                !s.body().contains("alias real"),
                "{s:?} must take `real` from the prelude"
            );
            let f64 = compose(s, Precision::F64);
            assert!(f64.contains("alias real = f64;") && !f64.contains(ALIAS_F32));
        }
    }

    /// Every variant parses and validates with naga (the compiler wgpu uses), with the
    /// capabilities its precision needs, on the CPU: a shader error shows up here without a
    /// device, and in every CI run.
    #[test]
    fn every_shader_variant_parses_and_validates() {
        use wgpu::naga;
        let variants = variants();
        assert_eq!(
            variants.len(),
            9,
            "3 impostors × 2 precisions + the pyramid, the slices and the octree"
        );
        for (shader, precision, source) in variants {
            let label = shader.label(precision);
            let module = naga::front::wgsl::parse_str(&source)
                .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(&source)));
            let caps = match precision {
                Precision::F32 => naga::valid::Capabilities::default(),
                Precision::F64 => {
                    naga::valid::Capabilities::default() | naga::valid::Capabilities::FLOAT64
                }
            };
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
                .validate(&module)
                .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(&source)));
            let entries: Vec<&str> = module
                .entry_points
                .iter()
                .map(|e| e.name.as_str())
                .collect();
            assert_eq!(entries, ["vs_main", "fs_main"], "{label}");
        }
    }
}

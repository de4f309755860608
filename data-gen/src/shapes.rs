//! The bundled procedural scene (docs/design.md §3.1), built for the default cylinder
//! `R = 1`, `H = 2`.

use glam::{DVec3, Vec3};

use crate::albedo::Albedo;
use crate::error::DataGenError;
use crate::rng::SplitMix64;
use crate::shape::{Csg, Part, Primitive};

/// Names accepted by [`scene_shape`].
pub const SCENE_SHAPES: &[&str] = &[
    "sphere", "box", "torus", "capsule", "pear", "truck", "chair", "tree", "building",
];

fn part(primitive: Primitive, albedo: Albedo) -> Part {
    Part { primitive, albedo }
}

fn solid(r: f32, g: f32, b: f32) -> Albedo {
    Albedo::Solid(Vec3::new(r, g, b))
}

/// A procedural shape of the bundled scene by name (see [`SCENE_SHAPES`]):
///
/// * `sphere` — radius 0.8 on the axis, striped by azimuth;
/// * `box` — a checkered box turned by 0.4 rad;
/// * `torus` — a ring with a horizontal axis;
/// * `capsule` — a slanted capsule;
/// * `pear` — two balls and a stem on the axis (star-shaped slices);
/// * `truck` — a body, a cabin and four wheels off the axis;
/// * `chair` — a seat, a back and four legs parallel to the axis (the cylindrical texture's known
///   failure);
/// * `tree` — a trunk and a crown of 90 small balls (seeded);
/// * `building` — two blocks with flat faces and windows on four storeys.
pub fn scene_shape(name: &str) -> Result<Csg, DataGenError> {
    let v = DVec3::new;
    let parts = match name {
        "sphere" => vec![part(
            Primitive::Sphere {
                center: v(0.0, 1.0, 0.0),
                radius: 0.8,
            },
            Albedo::Stripes {
                a: Vec3::new(0.9, 0.3, 0.2),
                b: Vec3::new(0.95, 0.85, 0.3),
                count: 8,
            },
        )],
        "box" => vec![part(
            Primitive::Box {
                center: v(0.0, 1.0, 0.0),
                half: v(0.5, 0.6, 0.4),
                yaw: 0.4,
            },
            Albedo::Checker {
                a: Vec3::new(0.2, 0.4, 0.8),
                b: Vec3::new(0.9, 0.9, 0.9),
                cell: 0.2,
            },
        )],
        "torus" => vec![part(
            Primitive::Torus {
                center: v(0.0, 1.0, 0.0),
                axis: DVec3::Z,
                major: 0.6,
                minor: 0.22,
            },
            Albedo::Stripes {
                a: Vec3::new(0.2, 0.7, 0.3),
                b: Vec3::new(0.9, 0.9, 0.5),
                count: 6,
            },
        )],
        "capsule" => vec![part(
            Primitive::Capsule {
                a: v(-0.4, 0.4, 0.2),
                b: v(0.4, 1.6, -0.2),
                radius: 0.3,
            },
            solid(0.8, 0.5, 0.2),
        )],
        "pear" => {
            let skin = Albedo::Stripes {
                a: Vec3::new(0.75, 0.8, 0.25),
                b: Vec3::new(0.6, 0.7, 0.2),
                count: 12,
            };
            vec![
                part(
                    Primitive::Sphere {
                        center: v(0.0, 0.62, 0.0),
                        radius: 0.6,
                    },
                    skin.clone(),
                ),
                part(
                    Primitive::Sphere {
                        center: v(0.03, 1.22, 0.0),
                        radius: 0.38,
                    },
                    skin,
                ),
                part(
                    Primitive::Capsule {
                        a: v(0.03, 1.5, 0.0),
                        b: v(0.1, 1.85, 0.02),
                        radius: 0.04,
                    },
                    solid(0.35, 0.2, 0.1),
                ),
            ]
        }
        "truck" => {
            let tyre = solid(0.08, 0.08, 0.08);
            let mut parts = vec![
                part(
                    Primitive::Box {
                        center: v(0.15, 0.6, 0.0),
                        half: v(0.72, 0.28, 0.36),
                        yaw: 0.0,
                    },
                    Albedo::Checker {
                        a: Vec3::new(0.8, 0.15, 0.1),
                        b: Vec3::new(0.9, 0.6, 0.1),
                        cell: 0.25,
                    },
                ),
                part(
                    Primitive::Box {
                        center: v(-0.55, 1.05, 0.0),
                        half: v(0.22, 0.2, 0.33),
                        yaw: 0.0,
                    },
                    solid(0.15, 0.3, 0.8),
                ),
            ];
            for x in [-0.45, 0.5] {
                for z in [-0.28, 0.28] {
                    let dz = if z > 0.0 { 0.14 } else { -0.14 };
                    parts.push(part(
                        Primitive::Cylinder {
                            a: v(x, 0.22, z),
                            b: v(x, 0.22, z + dz),
                            radius: 0.2,
                        },
                        tyre.clone(),
                    ));
                }
            }
            parts
        }
        "chair" => {
            let wood = solid(0.6, 0.4, 0.2);
            let mut parts = vec![
                part(
                    Primitive::Box {
                        center: v(0.0, 0.9, 0.0),
                        half: v(0.5, 0.05, 0.5),
                        yaw: 0.0,
                    },
                    Albedo::Checker {
                        a: Vec3::new(0.7, 0.5, 0.3),
                        b: Vec3::new(0.5, 0.3, 0.15),
                        cell: 0.2,
                    },
                ),
                part(
                    Primitive::Box {
                        center: v(0.0, 1.4, -0.45),
                        half: v(0.5, 0.45, 0.05),
                        yaw: 0.0,
                    },
                    wood.clone(),
                ),
            ];
            for x in [-0.42, 0.42] {
                for z in [-0.42, 0.42] {
                    parts.push(part(
                        Primitive::Cylinder {
                            a: v(x, 0.0, z),
                            b: v(x, 0.85, z),
                            radius: 0.05,
                        },
                        wood.clone(),
                    ));
                }
            }
            parts
        }
        "tree" => {
            let mut rng = SplitMix64::new(0x7EE);
            let mut parts = vec![part(
                Primitive::Cylinder {
                    a: v(0.0, 0.0, 0.0),
                    b: v(0.0, 0.85, 0.0),
                    radius: 0.09,
                },
                solid(0.4, 0.25, 0.1),
            )];
            for _ in 0..90 {
                // Rejection-sample a point in the crown ellipsoid.
                let c = loop {
                    let c = v(
                        rng.range(-1.0, 1.0),
                        rng.range(-1.0, 1.0),
                        rng.range(-1.0, 1.0),
                    );
                    if c.length_squared() <= 1.0 {
                        break c;
                    }
                };
                let radius = rng.range(0.1, 0.17);
                let center = v(0.66 * c.x, 1.3 + 0.52 * c.y, 0.66 * c.z);
                let g = rng.range(0.35, 0.75) as f32;
                parts.push(part(
                    Primitive::Sphere { center, radius },
                    solid(0.15 * g, g, 0.2 * g),
                ));
            }
            parts
        }
        "building" => {
            let facade = Albedo::Windows {
                wall: Vec3::new(0.75, 0.7, 0.6),
                glass: Vec3::new(0.15, 0.25, 0.4),
                storey: 0.35,
                pitch: 0.25,
            };
            vec![
                part(
                    Primitive::Box {
                        center: v(0.0, 0.7, 0.0),
                        half: v(0.58, 0.7, 0.4),
                        yaw: 0.3,
                    },
                    facade.clone(),
                ),
                part(
                    Primitive::Box {
                        center: v(0.1, 1.6, 0.05),
                        half: v(0.35, 0.2, 0.28),
                        yaw: 0.3,
                    },
                    facade,
                ),
            ]
        }
        _ => {
            return Err(DataGenError::UnknownShape {
                name: name.to_string(),
                known: SCENE_SHAPES.join(", "),
            });
        }
    };
    Csg::new(name, parts)
}

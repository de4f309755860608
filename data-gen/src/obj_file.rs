//! Wavefront OBJ input (`tobj`) with its MTL materials: flat diffuse colours and vertex colours
//! as before textures, and textured or alpha-tested materials read through the `surface` module
//! (`Kd × map_Kd`, `map_d`, `d`, and `Ke × map_Ke` for light given off; see
//! `docs/real-assets.md`). Every MTL and texture file read is
//! listed with its hash for the cache.

use std::path::Path;
use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

use crate::error::DataGenError;
use crate::mesh::{Extras, Loaded, MeshLoadOptions, TriColor};
use crate::placement::UpAxis;
use crate::surface::{Material, MaterialAlpha, SurfaceTri, TextureImage, TextureRef};

/// The triangles of the OBJ text `bytes` read from `path` (materials and textures are read
/// from its folder), their colours, and what the normalisation needs besides.
pub(crate) fn load(
    bytes: &[u8],
    path: &Path,
    options: &MeshLoadOptions,
) -> Result<Loaded, DataGenError> {
    if std::str::from_utf8(bytes).is_err() {
        return Err(DataGenError::ObjParse {
            path: path.to_path_buf(),
            message: "the file is not text (invalid UTF-8)".into(),
        });
    }
    let load = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    // As `tobj::load_obj` does, from the bytes: materials relative to the file's folder
    // (read here, so that they are hashed with the mesh).
    let folder = path.parent().unwrap_or(Path::new(""));
    let read_mtl = std::sync::Mutex::new(Vec::new());
    // Why an MTL file was refused before tobj read it (tobj panics on a colour line of fewer
    // than three numbers).
    let refused = std::sync::Mutex::new(None::<String>);
    let (models, materials) = tobj::load_obj_buf(&mut &bytes[..], &load, |mtl| {
        let file = folder.join(mtl);
        let text = std::fs::read(&file).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        if let Ok(mut read) = read_mtl.lock() {
            read.push((file.clone(), blake3::hash(&text)));
        }
        if let Some(why) = short_colour_line(&text) {
            if let Ok(mut r) = refused.lock() {
                *r = Some(format!("{}: {why}", file.display()));
            }
            return Err(tobj::LoadError::MaterialParseError);
        }
        tobj::load_mtl_buf(&mut &text[..])
    })
    .map_err(|e| DataGenError::ObjParse {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    // A material file that is absent leaves the fallback colours (many OBJ files name one they
    // were not shipped with); one that is there but malformed is an error.
    let materials = match materials {
        Ok(m) => m,
        Err(tobj::LoadError::OpenFileFailed) => Vec::new(),
        Err(e) => {
            return Err(DataGenError::ObjParse {
                path: path.to_path_buf(),
                message: refused
                    .lock()
                    .ok()
                    .and_then(|mut r| r.take())
                    .unwrap_or_else(|| format!("its material file: {e}")),
            });
        }
    };
    let mut inputs = read_mtl.into_inner().unwrap_or_default();
    // Materials with a texture or alpha are read through the `surface` module; the others
    // keep their flat diffuse colour.
    let mut surface_materials = Vec::new();
    let mut surface_of = vec![None; materials.len()];
    let mut images: Vec<(String, Arc<TextureImage>)> = Vec::new();
    let mut texture = |name: &str, material: &str, srgb: bool, inputs: &mut Vec<_>| {
        // `map_Kd -s 1 1 1 file.png`: the file is the last word.
        let name = name.split_whitespace().last().unwrap_or(name);
        if let Some((_, img)) = images.iter().find(|(n, _)| n == name) {
            return Ok(TextureRef::from_image(Arc::clone(img)));
        }
        let file = folder.join(name.replace('\\', "/"));
        let bad = |message: String| DataGenError::Texture {
            path: file.clone(),
            material: material.to_string(),
            message,
        };
        let data = std::fs::read(&file).map_err(|e| bad(e.to_string()))?;
        inputs.push((file.clone(), blake3::hash(&data)));
        let img = Arc::new(TextureImage::decode(&data, srgb).map_err(bad)?);
        images.push((name.to_string(), Arc::clone(&img)));
        Ok::<_, DataGenError>(TextureRef::from_image(img))
    };
    for (k, mat) in materials.iter().enumerate() {
        // Material values are read in f64 (the feature that reads positions in f64) and kept
        // in f32, as every colour is.
        let dissolve = mat.dissolve.map_or(1.0, |d| d as f32);
        // `Ke r g b` (tobj parses it; malformed text fails the whole file there): emitted
        // linear RGB, non-negative and finite.
        let emissive = match mat.emissive.map(|ke| ke.map(|c| c as f32)) {
            None => Vec3::ZERO,
            Some(ke) if ke.iter().all(|c| c.is_finite() && *c >= 0.0) => Vec3::from(ke),
            Some(ke) => {
                return Err(DataGenError::ObjParse {
                    path: path.to_path_buf(),
                    message: format!(
                        "material '{}': Ke {ke:?} is not three finite non-negative numbers",
                        mat.name
                    ),
                });
            }
        };
        if mat.diffuse_texture.is_none()
            && mat.dissolve_texture.is_none()
            && dissolve >= 1.0
            && emissive == Vec3::ZERO
        {
            continue;
        }
        let kd = mat.diffuse.map_or([1.0; 3], |d| d.map(|c| c as f32));
        let base_texture = match &mat.diffuse_texture {
            Some(t) => Some((texture(t, &mat.name, true, &mut inputs)?, 0)),
            None => None,
        };
        let alpha_texture = match &mat.dissolve_texture {
            Some(t) => Some(texture(t, &mat.name, false, &mut inputs)?),
            None => None,
        };
        // A cut-out map is a mask (cutoff ½); a uniform dissolve below 1 is coverage.
        let alpha_mode = if alpha_texture.is_some() {
            MaterialAlpha::Mask { cutoff: 0.5 }
        } else if dissolve < 1.0 {
            MaterialAlpha::Blend
        } else {
            MaterialAlpha::Opaque
        };
        let emissive_texture = match mat.unknown_param.get("map_Ke") {
            Some(t) if emissive != Vec3::ZERO => {
                Some((texture(t, &mat.name, true, &mut inputs)?, 0))
            }
            _ => None,
        };
        surface_of[k] = Some(surface_materials.len() as u32);
        surface_materials.push(Material {
            name: mat.name.clone(),
            base_color: Vec4::new(kd[0], kd[1], kd[2], dissolve.clamp(0.0, 1.0)),
            base_texture,
            alpha_texture,
            alpha_mode,
            normal_map: None,
            single_sided: false,
            emissive,
            emissive_texture,
            unlit: false,
        });
    }
    let total: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    let mut positions = Vec::with_capacity(total);
    let mut colors = Vec::with_capacity(total);
    for model in &models {
        let m = &model.mesh;
        let faces = m.indices.len() / 3;
        // The first face corner (in file order) that refers to a missing vertex.
        let vertices = m.positions.len() / 3;
        if let Some(&i) = m.indices[..3 * faces]
            .iter()
            .find(|&&i| i as usize >= vertices)
        {
            return Err(DataGenError::ObjParse {
                path: path.to_path_buf(),
                message: format!("face refers to vertex {} which does not exist", i + 1),
            });
        }
        let vertex = |k: usize| {
            let i = 3 * m.indices[k] as usize;
            let p = &m.positions[i..i + 3];
            [p[0], p[1], p[2]]
        };
        let material_color = m
            .material_id
            .and_then(|id| materials.get(id))
            .and_then(|mat| mat.diffuse)
            .map(|d| Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32));
        let surface = m
            .material_id
            .and_then(|id| surface_of.get(id).copied().flatten());
        let has_vc = m.vertex_color.len() == m.positions.len() && !m.vertex_color.is_empty();
        let has_uv = m.texcoord_indices.len() == m.indices.len()
            && m.texcoord_indices
                .iter()
                .all(|&i| 2 * (i as usize) + 1 < m.texcoords.len());
        positions.par_extend(
            (0..faces)
                .into_par_iter()
                .map(|tri| [vertex(3 * tri), vertex(3 * tri + 1), vertex(3 * tri + 2)]),
        );
        colors.par_extend((0..faces).into_par_iter().map(|tri| {
            let vc = |k: usize| {
                let i = m.indices[3 * tri + k] as usize;
                if has_vc {
                    let c = &m.vertex_color[3 * i..3 * i + 3];
                    Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, 1.0)
                } else {
                    Vec4::ONE
                }
            };
            if let Some(material) = surface {
                // OBJ's `v` points up the image; the surface convention's points down.
                let uv = |k: usize| {
                    if has_uv {
                        let i = 2 * m.texcoord_indices[3 * tri + k] as usize;
                        Vec2::new(m.texcoords[i] as f32, 1.0 - m.texcoords[i + 1] as f32)
                    } else {
                        Vec2::ZERO
                    }
                };
                let uv = [uv(0), uv(1), uv(2)];
                TriColor::Surface(SurfaceTri {
                    material,
                    uv: [uv, uv],
                    color: [vc(0), vc(1), vc(2)],
                    normal: None,
                    tangent: None,
                })
            } else if has_vc {
                let c = |k: usize| {
                    let i = m.indices[3 * tri + k] as usize;
                    Vec3::new(
                        m.vertex_color[3 * i] as f32,
                        m.vertex_color[3 * i + 1] as f32,
                        m.vertex_color[3 * i + 2] as f32,
                    )
                };
                TriColor::Vertex([c(0), c(1), c(2)])
            } else if let Some(c) = material_color {
                TriColor::Flat(c)
            } else {
                TriColor::Procedural
            }
        }));
    }
    let mut notes = Vec::new();
    if options.up == UpAxis::PosY {
        notes.push("OBJ declares no up axis: +y taken as up".to_string());
    }
    let extras = Extras {
        materials: surface_materials,
        notes,
        inputs,
        units: "file unit",
    };
    Ok((positions, colors, extras))
}

/// The first colour line (`Ka`, `Kd`, `Ks`, `Ke`) of MTL `text` with fewer than three values, as
/// `line N: ...`; `None` when every one has three or more.
fn short_colour_line(text: &[u8]) -> Option<String> {
    String::from_utf8_lossy(text)
        .lines()
        .enumerate()
        .find_map(|(k, line)| {
            let mut words = line.split_whitespace();
            let key = words.next()?;
            let values = words.count();
            (["Ka", "Kd", "Ks", "Ke"].contains(&key) && values < 3)
                .then(|| format!("line {}: {key} needs three numbers, found {values}", k + 1))
        })
}

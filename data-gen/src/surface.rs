//! Materials of real assets: base-colour textures and factors, vertex colours, shading normals and
//! alpha (glTF 2.0's metallic-roughness base colour, and OBJ/MTL's `Kd`, `map_Kd`, `d`, `map_d`).
//!
//! Conventions, fixed here:
//! * Texels are stored **linear** RGBA `f32`; base-colour images (sRGB by the glTF specification
//!   and by MTL practice) are decoded to linear when loaded; alpha is never sRGB-coded.
//! * Texture coordinates have `(0, 0)` at the image's **top-left** texel corner and `(1, 1)` at
//!   its bottom-right (glTF's convention; OBJ's `vt` has `v` upward and is flipped when loaded).
//!   Texel `(i, j)` has its centre at `((i + ½)/w, (j + ½)/h)`.
//! * The colour at a surface point is `factor × texture(uv) × vertex colour`, RGBA, in linear
//!   space; the albedo is its RGB and the coverage test reads its alpha ([`MaterialAlpha`]).
//! * A point lookup is bilinear between the four nearest texel centres (or nearest, as the sampler
//!   says), with the sampler's wrap mode per axis.
//! * A lookup over a footprint (a grid of rays: each ray stands for its cell of the grid, see
//!   `docs/real-assets.md`) reads the image's mip chain (2 × 2 box averages in linear light)
//!   trilinearly at the level where the footprint's minor axis spans one texel, with up to
//!   [`MAX_ANISOTROPY`] lookups spread along the major axis: the capture's one ray per pixel then
//!   reads what the truth's `k × k` rays average, and neither aliases.

use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3, Vec3A, Vec4, Vec4Swizzles};
use obvhs::triangle::Triangle;

/// How a texture coordinate outside `[0, 1]` wraps (glTF sampler `wrapS` / `wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tiles the texture (glTF `REPEAT`, the default).
    #[default]
    Repeat,
    /// Tiles it mirrored every other period (glTF `MIRRORED_REPEAT`).
    MirroredRepeat,
    /// Holds the edge texel (glTF `CLAMP_TO_EDGE`).
    ClampToEdge,
}

impl Wrap {
    /// The texel index for integer index `i` of a texture `n` texels across.
    #[inline]
    fn index(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let k = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
            Wrap::ClampToEdge => i.clamp(0, n - 1),
        };
        k as usize
    }
}

/// How texels are combined at a lookup (the glTF sampler's magnification filter).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SamplerFilter {
    /// The nearest texel (glTF `NEAREST`).
    Nearest,
    /// Bilinear between the four nearest texel centres (glTF `LINEAR`, and the default).
    #[default]
    Linear,
}

/// Most lookups a footprint lookup spreads along its major axis (beyond, the level is raised).
pub const MAX_ANISOTROPY: usize = 8;

/// One level of a mip chain.
#[derive(Clone, Debug, PartialEq)]
struct Level {
    width: usize,
    height: usize,
    texels: Vec<Vec4>,
}

impl Level {
    /// The next level: `⌈w/2⌉ × ⌈h/2⌉`, each texel the mean of its (up to) 2 × 2 parents.
    fn half(&self) -> Level {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let texels = (0..w * h)
            .map(|k| {
                let (i, j) = (k % w, k / w);
                let (i0, j0) = (2 * i, 2 * j);
                let (i1, j1) = ((i0 + 1).min(self.width - 1), (j0 + 1).min(self.height - 1));
                let at = |i: usize, j: usize| self.texels[i + self.width * j];
                (at(i0, j0) + at(i1, j0) + at(i0, j1) + at(i1, j1)) * 0.25
            })
            .collect();
        Level {
            width: w,
            height: h,
            texels,
        }
    }
}

/// An image of linear RGBA texels, row 0 at the top, with its mip chain.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureImage {
    width: usize,
    height: usize,
    texels: Vec<Vec4>,
    /// Levels 1, 2, … down to 1 × 1.
    mips: Vec<Level>,
    /// The PNG or JPEG file it was decoded from, when it was (a writer copies it instead of
    /// encoding the texels again).
    encoded: Option<EncodedImage>,
}

/// The bytes of an image file as a source held it.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedImage {
    /// The file's bytes.
    pub bytes: Arc<[u8]>,
    /// `"image/png"` or `"image/jpeg"`.
    pub mime: &'static str,
}

impl TextureImage {
    /// An image of `width × height` texels in row-major order from the top row, with its mip
    /// chain (cost: a third more memory and one pass over the texels). `None` when a size is
    /// zero or `texels` has the wrong length.
    pub fn new(width: usize, height: usize, texels: Vec<Vec4>) -> Option<Self> {
        if !(width > 0 && height > 0 && width.checked_mul(height) == Some(texels.len())) {
            return None;
        }
        let mut mips = Vec::new();
        let mut level = Level {
            width,
            height,
            texels,
        };
        while level.width > 1 || level.height > 1 {
            let next = level.half();
            mips.push(std::mem::replace(&mut level, next));
        }
        mips.push(level);
        // `mips` now holds every level from 0; level 0 moves out.
        let base = mips.remove(0);
        Some(Self {
            width,
            height,
            texels: base.texels,
            mips,
            encoded: None,
        })
    }

    /// Decodes a PNG or JPEG file (any format `image` reads) as [`TextureImage::from_dynamic`]
    /// does, keeping the file's bytes when it is PNG or JPEG ([`TextureImage::encoded`]).
    /// Errors: the decoder's message, or an empty image.
    pub fn decode(data: &[u8], srgb: bool) -> Result<Self, String> {
        let img = image::load_from_memory(data).map_err(|e| format!("image decode failed: {e}"))?;
        let mut t = Self::from_dynamic(&img, srgb).ok_or("the image is empty")?;
        let mime = match image::guess_format(data) {
            Ok(image::ImageFormat::Png) => Some("image/png"),
            Ok(image::ImageFormat::Jpeg) => Some("image/jpeg"),
            _ => None,
        };
        t.encoded = mime.map(|mime| EncodedImage {
            bytes: data.into(),
            mime,
        });
        Ok(t)
    }

    /// The PNG or JPEG file this image was decoded from ([`TextureImage::decode`]), if any.
    pub fn encoded(&self) -> Option<&EncodedImage> {
        self.encoded.as_ref()
    }

    /// Level `l` (0 is the image) as `(width, height, texels)`.
    fn level(&self, l: usize) -> (usize, usize, &[Vec4]) {
        if l == 0 {
            (self.width, self.height, &self.texels)
        } else {
            let m = &self.mips[(l - 1).min(self.mips.len() - 1)];
            (m.width, m.height, &m.texels)
        }
    }

    /// The image reduced to at most `max_side` texels on a side: the first level of its mip
    /// chain that fits (each texel the mean of its parents, in linear values), snapped to the
    /// 8-bit codes a file holds (RGB through the sRGB curve when `srgb`, as colour textures
    /// are read; alpha and linear data straight), as an image of its own with its own chain and
    /// no source file. `None` when the image already fits or `max_side` is 0. Cost: a copy of
    /// that level's texels.
    pub fn reduced(&self, max_side: usize, srgb: bool) -> Option<TextureImage> {
        if max_side == 0 || self.width.max(self.height) <= max_side {
            return None;
        }
        let snap = |c: f32, k: usize| {
            let c = c.clamp(0.0, 1.0);
            if srgb && k < 3 {
                let code = (crate::image_io::linear_to_srgb(c) * 255.0).round() / 255.0;
                crate::image_io::srgb_to_linear(code)
            } else {
                (c * 255.0).round() / 255.0
            }
        };
        (1..self.levels())
            .map(|l| self.level(l))
            .find(|(w, h, _)| (*w).max(*h) <= max_side)
            .and_then(|(w, h, texels)| {
                let texels = texels
                    .iter()
                    .map(|t| Vec4::new(snap(t.x, 0), snap(t.y, 1), snap(t.z, 2), snap(t.w, 3)))
                    .collect();
                TextureImage::new(w, h, texels)
            })
    }

    /// Number of levels, the image included.
    pub fn levels(&self) -> usize {
        1 + self.mips.len()
    }

    /// The texture over a footprint: centre `uv`, the footprint's two axes `axes` in texture
    /// coordinates (module conventions). Falls back to [`TextureImage::sample`] where the
    /// footprint is below a texel or not finite.
    pub fn sample_footprint(
        &self,
        uv: Vec2,
        axes: [Vec2; 2],
        filter: SamplerFilter,
        wrap: [Wrap; 2],
    ) -> Vec4 {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let (a, b) = (axes[0] * size, axes[1] * size);
        let (la, lb) = (a.length(), b.length());
        if !(la.is_finite() && lb.is_finite()) || la.max(lb) <= 1.0 {
            return self.sample(uv, filter, wrap);
        }
        let (major, lmajor, lminor) = if la >= lb {
            (axes[0], la, lb)
        } else {
            (axes[1], lb, la)
        };
        let n = ((lmajor / lminor.max(1e-6)).ceil() as usize).clamp(1, MAX_ANISOTROPY);
        let width = (lmajor / n as f32).max(lminor);
        let lod = width.max(1.0).log2();
        (0..n)
            .map(|i| {
                let s = (i as f32 + 0.5) / n as f32 - 0.5;
                self.sample_lod(uv + major * s, lod, wrap)
            })
            .sum::<Vec4>()
            / n as f32
    }

    /// Trilinear lookup at level `lod` (fractional; clamped to the chain).
    fn sample_lod(&self, uv: Vec2, lod: f32, wrap: [Wrap; 2]) -> Vec4 {
        let top = (self.levels() - 1) as f32;
        let lod = lod.clamp(0.0, top);
        let l0 = lod.floor() as usize;
        let f = lod - l0 as f32;
        let a = self.bilinear(l0, uv, wrap);
        if f == 0.0 {
            a
        } else {
            a.lerp(self.bilinear(l0 + 1, uv, wrap), f)
        }
    }

    /// Bilinear lookup in level `l`.
    fn bilinear(&self, l: usize, uv: Vec2, wrap: [Wrap; 2]) -> Vec4 {
        let (w, h, texels) = self.level(l);
        let (x, y) = texel_coordinates(uv, w, h);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let at = |i: i64, j: i64| texels[wrap[0].index(i, w) + w * wrap[1].index(j, h)];
        let top = at(x0, y0).lerp(at(x0 + 1, y0), fx);
        let bottom = at(x0, y0 + 1).lerp(at(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }

    /// Decodes an 8- or 16-bit image: RGB from sRGB to linear when `srgb`, alpha as stored
    /// (1 where the image has none).
    pub fn from_dynamic(img: &image::DynamicImage, srgb: bool) -> Option<Self> {
        let rgba = img.to_rgba32f();
        let (w, h) = (rgba.width() as usize, rgba.height() as usize);
        let decode = |c: f32| {
            if srgb {
                crate::image_io::srgb_to_linear(c)
            } else {
                c
            }
        };
        let texels = rgba
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                Vec4::new(decode(r), decode(g), decode(b), a)
            })
            .collect();
        Self::new(w, h, texels)
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Texel `(i, j)` (column, row from the top).
    #[inline]
    pub fn texel(&self, i: usize, j: usize) -> Vec4 {
        self.texels[i + self.width * j]
    }

    /// The texture at `uv` through `filter` and `wrap` (module conventions). Non-finite
    /// coordinates read texel `(0, 0)`.
    pub fn sample(&self, uv: Vec2, filter: SamplerFilter, wrap: [Wrap; 2]) -> Vec4 {
        match filter {
            SamplerFilter::Nearest => {
                let (x, y) = texel_coordinates(uv, self.width, self.height);
                let i = wrap[0].index(x.round() as i64, self.width);
                let j = wrap[1].index(y.round() as i64, self.height);
                self.texel(i, j)
            }
            SamplerFilter::Linear => self.bilinear(0, uv, wrap),
        }
    }
}

/// Texture coordinates `uv` in texels of a `w × h` image, texel centres at integers; non-finite
/// coordinates read as `(0, 0)`, and far outside the texture (beyond 2⁴⁰ periods, where an index
/// would overflow) they are clamped.
#[inline]
fn texel_coordinates(uv: Vec2, w: usize, h: usize) -> (f64, f64) {
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    let lim = 1e12;
    (
        (f64::from(uv.x) * w as f64 - 0.5).clamp(-lim, lim),
        (f64::from(uv.y) * h as f64 - 0.5).clamp(-lim, lim),
    )
}

/// An affine map of texture coordinates, `uv' = M·(u, v, 1)` (glTF `KHR_texture_transform`:
/// `T(offset)·R(rotation)·S(scale)`, the rotation counter-clockwise in the image as displayed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// The rows of the 2 × 3 matrix.
    pub rows: [[f32; 3]; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        Self {
            rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        }
    }
}

impl UvTransform {
    /// The transform of `KHR_texture_transform` with `offset`, `rotation` (radians) and `scale`.
    pub fn from_offset_rotation_scale(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Self {
        let (s, c) = rotation.sin_cos();
        // T · R · S with R = [[c, s], [−s, c]] (the extension's matrix, which turns the image
        // counter-clockwise because v points down).
        Self {
            rows: [
                [c * scale[0], s * scale[1], offset[0]],
                [-s * scale[0], c * scale[1], offset[1]],
            ],
        }
    }

    /// The transformed coordinates.
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [a, b] = self.rows;
        Vec2::new(
            a[0] * uv.x + a[1] * uv.y + a[2],
            b[0] * uv.x + b[1] * uv.y + b[2],
        )
    }
}

/// A texture as a material reads it: an image, its sampler and the coordinate transform.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    /// The image (shared between materials that use it).
    pub image: Arc<TextureImage>,
    /// The magnification filter (the minification filter is not used: no pyramid is read).
    pub filter: SamplerFilter,
    /// Wrap modes along `u` and `v`.
    pub wrap: [Wrap; 2],
    /// `KHR_texture_transform`, identity without it.
    pub transform: UvTransform,
}

impl TextureRef {
    /// `image` read bilinearly, repeated, without a coordinate transform (glTF's defaults).
    pub fn from_image(image: Arc<TextureImage>) -> Self {
        Self {
            image,
            filter: SamplerFilter::Linear,
            wrap: [Wrap::Repeat; 2],
            transform: UvTransform::default(),
        }
    }

    /// The texture at (untransformed) coordinates `uv`.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        self.image
            .sample(self.transform.apply(uv), self.filter, self.wrap)
    }

    /// The texture over the footprint of centre `uv` and axes `axes` (untransformed
    /// coordinates; see [`TextureImage::sample_footprint`]).
    #[inline]
    pub fn sample_footprint(&self, uv: Vec2, axes: [Vec2; 2]) -> Vec4 {
        let linear = |v: Vec2| {
            let [a, b] = self.transform.rows;
            Vec2::new(a[0] * v.x + a[1] * v.y, b[0] * v.x + b[1] * v.y)
        };
        self.image.sample_footprint(
            self.transform.apply(uv),
            axes.map(linear),
            self.filter,
            self.wrap,
        )
    }
}

/// What a surface's alpha means (glTF `alphaMode`; OBJ/MTL `d` and `map_d` read as `Mask`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum MaterialAlpha {
    /// Alpha is ignored: every hit is opaque.
    #[default]
    Opaque,
    /// A hit is opaque where alpha ≥ the cutoff and the ray passes through elsewhere.
    Mask {
        /// The cutoff (glTF `alphaCutoff`, default 0.5).
        cutoff: f32,
    },
    /// Fractional coverage: a ray is stopped with probability alpha, decided by a hash of the hit
    /// point and the triangle (a fixed, deterministic pattern, so that a supersampled picture's
    /// coverage converges to alpha and two runs give the same bytes).
    Blend,
}

/// A tangent-space normal map (glTF `normalTexture`): the texture's RGB (linear, not sRGB) is
/// `(n + 1)/2` of a unit normal in the frame `(T, B, N)` of the surface's tangent, bitangent and
/// shading normal; `scale` multiplies its `x` and `y` (glTF §3.9.3).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// The texture (decoded without the sRGB curve).
    pub texture: TextureRef,
    /// The texture coordinate set it reads (0 or 1).
    pub set: u32,
    /// glTF `normalTexture.scale` (default 1).
    pub scale: f32,
}

impl NormalMap {
    /// The shading normal at a hit: the map's texel `texel` (RGB in `[0, 1]`, read at the point
    /// or over a footprint) turned into the frame of the unit shading normal `n` and the tangent
    /// `tangent` (`xyz`, with the bitangent's handedness in `w`: `B = w · n × T`), after
    /// Gram–Schmidt makes `T` orthogonal to `n`. `None` where the frame or the result is
    /// degenerate (the caller keeps `n`).
    pub fn perturb(&self, texel: Vec4, n: Vec3, tangent: Vec4) -> Option<Vec3> {
        let t = (tangent.xyz() - n * n.dot(tangent.xyz())).try_normalize()?;
        let b = n.cross(t) * if tangent.w < 0.0 { -1.0 } else { 1.0 };
        let v = texel.xyz() * 2.0 - Vec3::ONE;
        (t * (v.x * self.scale) + b * (v.y * self.scale) + n * v.z).try_normalize()
    }
}

/// A surface material: base colour (factor × texture), alpha, and what altrep does not read.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Material {
    /// Name in the source file (may be empty).
    pub name: String,
    /// Linear RGBA factor (glTF `baseColorFactor`, MTL `Kd` with `d`).
    pub base_color: Vec4,
    /// Base-colour texture (glTF `baseColorTexture`, MTL `map_Kd`), if any, with the texture
    /// coordinate set it reads (0 or 1).
    pub base_texture: Option<(TextureRef, u32)>,
    /// Alpha-only texture (MTL `map_d`; its first channel, or its alpha when it has one).
    pub alpha_texture: Option<TextureRef>,
    /// How alpha is read.
    pub alpha_mode: MaterialAlpha,
    /// Tangent-space normal map (glTF `normalTexture`), if any.
    pub normal_map: Option<NormalMap>,
    /// Back faces let rays through (glTF `doubleSided: false`, its default): a ray meeting the
    /// side its winding turns away (geometric normal · direction > 0) passes, in every tracer
    /// but the inside tests. False for OBJ materials, which have no such notion.
    pub single_sided: bool,
    /// Linear RGB light the surface gives off whatever the lighting (glTF `emissiveFactor`,
    /// default black), multiplied by [`Material::emissive_texture`] where there is one.
    pub emissive: Vec3,
    /// Emissive texture (glTF `emissiveTexture`, sRGB-coded like the base colour) with the
    /// texture coordinate set it reads (0 or 1).
    pub emissive_texture: Option<(TextureRef, u32)>,
    /// Not lit (glTF `KHR_materials_unlit`): the surface shows its base colour (factor × texture
    /// × vertex colour) whatever the light, and [`Material::emissive`] is not read.
    pub unlit: bool,
}

impl Material {
    /// Linear RGBA at texture coordinates `uv` (sets 0 and 1) with vertex colour `vertex`.
    #[inline]
    pub fn color(&self, uv: [Vec2; 2], vertex: Vec4) -> Vec4 {
        self.color_with(uv, vertex, |t, s| t.sample(uv[s]))
    }

    /// The colour with the base-colour texture (`t`, of set `s`) read by `base`.
    #[inline]
    fn color_with(
        &self,
        uv: [Vec2; 2],
        vertex: Vec4,
        base: impl Fn(&TextureRef, usize) -> Vec4,
    ) -> Vec4 {
        let mut c = self.base_color * vertex;
        if let Some((t, set)) = &self.base_texture {
            c *= base(t, (*set as usize).min(1));
        }
        if let Some(t) = &self.alpha_texture {
            let a = t.sample(uv[0]);
            // A grey image without alpha carries coverage in its value.
            c.w *= if a.w < 1.0 { a.w } else { a.x };
        }
        c
    }

    /// [`Material::color`] with the base-colour texture read over a footprint: `axes[s]` are the
    /// footprint's two axes in the coordinates of set `s`. Alpha textures are read at the point,
    /// as the alpha test reads them.
    #[inline]
    pub fn color_over(&self, uv: [Vec2; 2], axes: [[Vec2; 2]; 2], vertex: Vec4) -> Vec4 {
        self.color_with(uv, vertex, |t, s| t.sample_footprint(uv[s], axes[s]))
    }

    /// Linear RGB light given off at `uv` (sets 0 and 1): [`Material::emissive`] × the emissive
    /// texture, read over the footprint `axes` (as [`Material::color_over`]) or at the point.
    /// Black for an unlit material (its base colour is what it shows) and for one whose factor
    /// is black, without reading the texture.
    #[inline]
    pub fn emission(&self, uv: [Vec2; 2], axes: Option<[[Vec2; 2]; 2]>) -> Vec3 {
        if self.unlit || self.emissive == Vec3::ZERO {
            return Vec3::ZERO;
        }
        match &self.emissive_texture {
            None => self.emissive,
            Some((t, set)) => {
                let s = (*set as usize).min(1);
                let texel = match axes {
                    Some(a) => t.sample_footprint(uv[s], a[s]),
                    None => t.sample(uv[s]),
                };
                self.emissive * texel.xyz()
            }
        }
    }

    /// Whether the surface's colour is not albedo shaded by the light alone: it is unlit or
    /// gives off light ([`Material::emission`]).
    pub fn emits(&self) -> bool {
        self.unlit || self.emissive != Vec3::ZERO
    }

    /// Whether alpha can stop a ray from hitting this material.
    pub fn is_cut_out(&self) -> bool {
        !matches!(self.alpha_mode, MaterialAlpha::Opaque)
    }
}

/// The per-triangle attributes of a material-coloured triangle: material, texture coordinates of
/// both sets, vertex colours and (when the source has them) shading normals and, for a
/// normal-mapped material, tangents (`xyz`, handedness in `w`), all per corner.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SurfaceTri {
    pub(crate) material: u32,
    pub(crate) uv: [[Vec2; 3]; 2],
    pub(crate) color: [Vec4; 3],
    pub(crate) normal: Option<[Vec3; 3]>,
    /// Boxed: most triangles have none, and the box keeps the record small.
    pub(crate) tangent: Option<Box<[Vec4; 3]>>,
}

impl SurfaceTri {
    /// Interpolates the texture coordinates and vertex colour at barycentric weights `w`.
    #[inline]
    pub(crate) fn at(&self, w: [f32; 3]) -> ([Vec2; 2], Vec4) {
        let uv = self.uv.map(|c| c[0] * w[0] + c[1] * w[1] + c[2] * w[2]);
        let color = self.color[0] * w[0] + self.color[1] * w[1] + self.color[2] * w[2];
        (uv, color)
    }
}

/// Whether a hit with `alpha` under `mode` stops the ray; `key` is a hash of the hit (used by
/// [`MaterialAlpha::Blend`] only).
#[inline]
pub(crate) fn stops(mode: MaterialAlpha, alpha: f32, key: u64) -> bool {
    match mode {
        MaterialAlpha::Opaque => true,
        MaterialAlpha::Mask { cutoff } => alpha >= cutoff,
        MaterialAlpha::Blend => {
            // SplitMix64's finaliser: a uniform threshold in [0, 1) per key.
            let mut z = key.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            let u = (z >> 40) as f32 / (1u64 << 24) as f32;
            alpha > u
        }
    }
}

/// The footprint `cell` (two world vectors across a ray along `dir`) carried onto the plane of
/// `tri` along the ray and mapped to texture coordinates of both sets: `None` where the ray
/// grazes the plane or the triangle's texture mapping is degenerate. Grazing footprints are
/// capped at 64 cells long.
pub(crate) fn uv_axes(
    tri: &Triangle,
    s: &SurfaceTri,
    cell: [DVec3; 2],
    dir: DVec3,
) -> Option<[[Vec2; 2]; 2]> {
    let v = |a: Vec3A| DVec3::new(a.x.into(), a.y.into(), a.z.into());
    let (e1, e2) = (v(tri.v1) - v(tri.v0), v(tri.v2) - v(tri.v0));
    let n = e1.cross(e2);
    let nd = n.dot(dir);
    // False for NaN as well.
    if nd.abs().partial_cmp(&(1e-12 * n.length())) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let (g00, g01, g11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = g00 * g11 - g01 * g01;
    if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let on_plane = |f: DVec3| {
        let q = f - dir * (n.dot(f) / nd);
        // A grazing ray stretches the cell without bound: cap it.
        let cap = 64.0 * f.length();
        if q.length() > cap {
            q * (cap / q.length())
        } else {
            q
        }
    };
    let bary = |q: DVec3| {
        let (r0, r1) = (e1.dot(q), e2.dot(q));
        (
            ((g11 * r0 - g01 * r1) / det) as f32,
            ((g00 * r1 - g01 * r0) / det) as f32,
        )
    };
    let (a0, a1) = (bary(on_plane(cell[0])), bary(on_plane(cell[1])));
    let axes = [0, 1].map(|set| {
        let uv = &s.uv[set];
        let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
        [d1 * a0.0 + d2 * a0.1, d1 * a1.0 + d2 * a1.1]
    });
    axes.iter().flatten().all(|a| a.is_finite()).then_some(axes)
}

/// Barycentric weights of point `p` (assumed in the triangle's plane) with respect to
/// `v0, v1, v2`, clamped to the triangle.
pub(crate) fn barycentric(tri: &Triangle, p: DVec3) -> [f32; 3] {
    let v = |a: Vec3A| DVec3::new(a.x.into(), a.y.into(), a.z.into());
    let (a, b, c) = (v(tri.v0), v(tri.v1), v(tri.v2));
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    let w1 = ((p - a).cross(c - a)).dot(n) / nn;
    let w2 = ((b - a).cross(p - a)).dot(n) / nn;
    let w = [1.0 - w1 - w2, w1, w2].map(|x| x.clamp(0.0, 1.0));
    let s: f64 = w.iter().sum();
    w.map(|x| (x / s) as f32)
}

#[cfg(test)]
mod tests {
    use approx::assert_abs_diff_eq;

    use super::*;

    fn checker() -> TextureImage {
        // 2 × 2: black, white / white, black.
        let (k, w) = (Vec4::new(0.0, 0.0, 0.0, 1.0), Vec4::ONE);
        TextureImage::new(2, 2, vec![k, w, w, k]).unwrap()
    }

    #[test]
    fn texel_centres_read_their_texel_and_wrap_modes_fold_as_specified() {
        let t = checker();
        let lin = [Wrap::Repeat; 2];
        assert_eq!(
            t.sample(Vec2::new(0.25, 0.25), SamplerFilter::Linear, lin),
            t.texel(0, 0)
        );
        assert_eq!(
            t.sample(Vec2::new(0.75, 0.25), SamplerFilter::Linear, lin),
            t.texel(1, 0)
        );
        // Halfway between two centres: the mean.
        assert_abs_diff_eq!(
            t.sample(Vec2::new(0.5, 0.25), SamplerFilter::Linear, lin).x,
            0.5
        );
        // One period away: the same texel.
        assert_eq!(
            t.sample(Vec2::new(1.25, -0.75), SamplerFilter::Linear, lin),
            t.texel(0, 0)
        );
        // Clamped: the edge texel.
        let clamp = [Wrap::ClampToEdge; 2];
        assert_eq!(
            t.sample(Vec2::new(7.0, 0.25), SamplerFilter::Linear, clamp),
            t.texel(1, 0)
        );
        // Mirrored: [1, 2) reads the texture backwards.
        let mirror = [Wrap::MirroredRepeat; 2];
        assert_eq!(
            t.sample(Vec2::new(1.25, 0.25), SamplerFilter::Nearest, mirror),
            t.texel(1, 0)
        );
        assert_eq!(
            t.sample(Vec2::new(1.75, 0.25), SamplerFilter::Nearest, mirror),
            t.texel(0, 0)
        );
        // NaN coordinates read texel (0, 0), never NaN.
        assert!(t.sample(Vec2::NAN, SamplerFilter::Linear, lin).is_finite());
        assert!(
            t.sample(Vec2::splat(1e30), SamplerFilter::Linear, lin)
                .is_finite()
        );
    }

    #[test]
    fn texture_transform_offsets_rotates_and_scales() {
        let t = UvTransform::from_offset_rotation_scale([0.5, 0.0], 0.0, [2.0, 3.0]);
        assert_eq!(t.apply(Vec2::new(1.0, 1.0)), Vec2::new(2.5, 3.0));
        // A quarter turn: u → −v direction of the stored matrix, as the extension writes it.
        let r = UvTransform::from_offset_rotation_scale(
            [0.0, 0.0],
            std::f32::consts::FRAC_PI_2,
            [1.0, 1.0],
        );
        let p = r.apply(Vec2::new(1.0, 0.0));
        assert_abs_diff_eq!(p.x, 0.0, epsilon = 1e-6);
        assert_abs_diff_eq!(p.y, -1.0, epsilon = 1e-6);
    }

    #[test]
    fn a_footprint_reads_the_mean_of_the_texels_it_covers() {
        // An 8 × 8 checker of black and white texels: its mean is ½ grey.
        let texels = (0..64)
            .map(|k| {
                if (k % 8 + k / 8) % 2 == 0 {
                    Vec4::ONE
                } else {
                    Vec4::new(0.0, 0.0, 0.0, 1.0)
                }
            })
            .collect();
        let t = TextureImage::new(8, 8, texels).unwrap();
        assert_eq!(t.levels(), 4);
        let wrap = [Wrap::Repeat; 2];
        // A footprint of a whole period (8 texels) at any centre: the mean.
        for c in [
            Vec2::new(0.3, 0.7),
            Vec2::new(0.5, 0.5),
            Vec2::new(-2.1, 5.3),
        ] {
            let axes = [Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)];
            assert_abs_diff_eq!(
                t.sample_footprint(c, axes, SamplerFilter::Linear, wrap).x,
                0.5,
                epsilon = 1e-6
            );
            // Elongated 8:1 along u, one texel across v: still the mean of a texel row pair.
            let thin = [Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0 / 8.0)];
            let v = t.sample_footprint(c, thin, SamplerFilter::Linear, wrap).x;
            assert!((0.0..=1.0).contains(&v), "{v}");
        }
        // A footprint below a texel is the point lookup.
        let small = [Vec2::new(0.01, 0.0), Vec2::new(0.0, 0.01)];
        let c = Vec2::new(0.3, 0.7);
        assert_eq!(
            t.sample_footprint(c, small, SamplerFilter::Nearest, wrap),
            t.sample(c, SamplerFilter::Nearest, wrap)
        );
        // Degenerate footprints never give NaN.
        assert!(
            t.sample_footprint(c, [Vec2::NAN, Vec2::ZERO], SamplerFilter::Linear, wrap)
                .is_finite()
        );
        assert!(
            t.sample_footprint(
                c,
                [Vec2::splat(1e30), Vec2::ZERO],
                SamplerFilter::Linear,
                wrap
            )
            .is_finite()
        );
    }

    #[test]
    fn blend_coverage_converges_to_alpha() {
        for alpha in [0.0f32, 0.1, 0.3, 0.5, 0.9, 1.0] {
            let n = 100_000u64;
            let stopped = (0..n)
                .filter(|&k| stops(MaterialAlpha::Blend, alpha, k))
                .count();
            assert_abs_diff_eq!(stopped as f64 / n as f64, f64::from(alpha), epsilon = 0.01);
        }
        assert!(stops(MaterialAlpha::Mask { cutoff: 0.5 }, 0.5, 0));
        assert!(!stops(MaterialAlpha::Mask { cutoff: 0.5 }, 0.499, 0));
    }
}

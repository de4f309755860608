//! The one list of representations. The manifest's `[asset.KEY]` tables (`pipeline::AssetSpec`), the
//! planner's and the pipeline's jobs, the names a run reports, and [`open`] (any asset folder,
//! whatever it holds) are generated from it; adding a representation is its folder and one line
//! here.

use std::path::Path;

use super::{PipelineError, Representation};
use crate::asset::AssetReader;

/// Calls `$callback!` once with every representation, in the order the manifest lists, the
/// pipeline builds and the report shows them, as `(key, Variant, Type, "doc")`: the manifest key
/// and `pipeline::AssetSpec` field, the [`AnyAsset`] variant, the type
/// implementing [`Representation`], and the field's documentation.
macro_rules! for_each_representation {
    ($callback:ident) => {
        $callback! {
            (parallax, Parallax, $crate::parallax::asset::Parallax,
                "Images with parallax ([`crate::parallax`]), if wanted."),
            (cylinder, Cylinder, $crate::cylinder::asset::Cylinder,
                "Cylindrical texture ([`crate::cylinder`]), if wanted."),
            (octree, Octree, $crate::ellipsoid::asset::OctreeRepr,
                "Ellipsoid octree ([`crate::ellipsoid`]), if wanted."),
            (pyramid, Pyramid, $crate::pyramid::asset::PyramidRepr,
                "Texture pyramid ([`crate::pyramid`]), if wanted (texture assets only)."),
            (sphere, Sphere, $crate::sphere::asset::SphereRepr,
                "Images with parallax from any direction ([`crate::sphere`]), if wanted."),
            (slices, Slices, $crate::slices::asset::SlicesRepr,
                "Stacks of alpha slices of the object ([`crate::slices`]), if wanted (baked lighting)."),
            (mesh_lod, MeshLod, $crate::mesh_lod::asset::MeshLodRepr,
                "Simplified meshes with their switch sizes ([`crate::mesh_lod`]), if wanted (mesh assets only)."),
            (auto, Auto, $crate::auto::asset::AutoRepr,
                "The automatic level-of-detail chain over simplified meshes and impostors ([`crate::auto`]), if wanted (mesh assets only)."),
        }
    };
}
pub(crate) use for_each_representation;

macro_rules! any_asset {
    ($(($key:ident, $variant:ident, $repr:ty, $doc:literal)),* $(,)?) => {
        /// Any representation's data, as [`open`] loads it from an asset folder.
        pub enum AnyAsset {
            $(
                #[doc = $doc]
                $variant(<$repr as Representation>::Data),
            )*
        }

        /// The representations' names ([`Representation::NAME`]: the folder names and the
        /// `representation` of `asset.json`), in the registry's order.
        pub const NAMES: &[&str] = &[$(<$repr>::NAME),*];

        /// Opens the asset folder `dir` (verifying every file's size and hash, see
        /// [`AssetReader::open`]) and loads whatever representation its `asset.json` names.
        /// Errors: the folder's files ([`crate::asset::AssetError`]), or a representation this
        /// build does not know (named). Cost: one read of every file in the folder.
        pub fn open(dir: &Path) -> Result<AnyAsset, PipelineError> {
            let r = AssetReader::open(dir)?;
            let name = r.description().representation.as_str();
            $(
                if name == <$repr>::NAME {
                    return Ok(AnyAsset::$variant(<$repr>::read(&r)?));
                }
            )*
            Err(r
                .content(format!(
                    "names the representation '{name}'; this build knows {}",
                    NAMES.join(", ")
                ))
                .into())
        }

        impl AnyAsset {
            /// The representation's name ([`Representation::NAME`]).
            pub fn name(&self) -> &'static str {
                match self {
                    $(AnyAsset::$variant(_) => <$repr>::NAME,)*
                }
            }
        }
    };
}
for_each_representation!(any_asset);

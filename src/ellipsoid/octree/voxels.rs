//! The input of a build: voxels ([`Voxel`]), any source of them ([`VoxelSource`]) and a dense
//! grid ([`VoxelGrid`]).

use rayon::prelude::*;

use crate::ellipsoid::error::EllipsoidError;
/// One input voxel, kept at its old path; it lives in `altrep_data_gen` with the volumes.
pub use altrep_data_gen::Voxel;

/// A voxelised volume the octree can be built from (random access, shared between threads).
pub trait VoxelSource: Sync {
    /// `[nx, ny, nz]`, each ≥ 1.
    fn dims(&self) -> [usize; 3];
    /// The voxel at `(x, y, z)`, `x < nx`, `y < ny`, `z < nz`.
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel;
    /// Its density alone (the build reads colour and normal only where this is non-zero);
    /// override when it is cheaper than [`Self::voxel`].
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.voxel(x, y, z).density
    }
    /// Axes along which the volume tiles (neighbours wrap around). Default: none.
    fn periodic(&self) -> [bool; 3] {
        [false; 3]
    }
}

/// `altrep_data_gen`'s voxelised shapes (density, colour, normal; periodic axes honoured).
impl VoxelSource for altrep_data_gen::Volume {
    fn dims(&self) -> [usize; 3] {
        self.dims
    }
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let i = self.index(x, y, z);
        Voxel {
            density: self.density[i],
            color: self.color[i],
            normal: self.normal[i].map(|n| n.to_array()),
        }
    }
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.density[self.index(x, y, z)]
    }
    fn periodic(&self) -> [bool; 3] {
        self.periodic
    }
}

/// A dense voxel grid, index `x + nx (y + ny z)` (the layout of `altrep_data_gen`'s volumes).
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    dims: [usize; 3],
    density: Vec<f32>,
    color: Vec<[f32; 3]>,
    normal: Vec<Option<[f32; 3]>>,
}

impl VoxelGrid {
    /// A grid from its arrays; errors if a dimension is 0 or an array has the wrong length.
    pub fn new(
        dims: [usize; 3],
        density: Vec<f32>,
        color: Vec<[f32; 3]>,
        normal: Vec<Option<[f32; 3]>>,
    ) -> Result<Self, EllipsoidError> {
        let n = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n > 0)
            .ok_or_else(|| EllipsoidError::BadVolume(format!("bad dimensions {dims:?}")))?;
        for (name, len) in [
            ("density", density.len()),
            ("color", color.len()),
            ("normal", normal.len()),
        ] {
            if len != n {
                return Err(EllipsoidError::BadVolume(format!(
                    "{name} has {len} entries, dims {dims:?} need {n}"
                )));
            }
        }
        Ok(Self {
            dims,
            density,
            color,
            normal,
        })
    }

    /// Samples every voxel of `src` into a dense grid (rayon over z-slices).
    pub fn from_source<S: VoxelSource + ?Sized>(src: &S) -> Result<Self, EllipsoidError> {
        let dims = src.dims();
        let voxels: Vec<Voxel> = (0..dims[2])
            .into_par_iter()
            .flat_map_iter(|z| {
                (0..dims[1]).flat_map(move |y| (0..dims[0]).map(move |x| src.voxel(x, y, z)))
            })
            .collect();
        Self::new(
            dims,
            voxels.iter().map(|v| v.density).collect(),
            voxels.iter().map(|v| v.color).collect(),
            voxels.iter().map(|v| v.normal).collect(),
        )
    }
}

impl VoxelSource for VoxelGrid {
    fn dims(&self) -> [usize; 3] {
        self.dims
    }
    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        let i = x + self.dims[0] * (y + self.dims[1] * z);
        Voxel {
            density: self.density[i],
            color: self.color[i],
            normal: self.normal[i],
        }
    }
    fn density(&self, x: usize, y: usize, z: usize) -> f32 {
        self.density[x + self.dims[0] * (y + self.dims[1] * z)]
    }
}

/// An analytic volume ([`altrep_data_gen::AnalyticVolume`], `n³` voxels) as an octree input.
impl VoxelSource for altrep_data_gen::AnalyticVolume {
    fn dims(&self) -> [usize; 3] {
        [self.n; 3]
    }

    fn voxel(&self, x: usize, y: usize, z: usize) -> Voxel {
        self.sample(x, y, z)
    }
}

//! The ellipsoid octree on the GPU: the fragment-shader twin of
//! `altrep::ellipsoid::Octree::render_view_counted`, in `f32` (what an engine ships).
//!
//! Per fragment, the shader (`octree.wgsl`) clips the ray through the pixel centre to the cube,
//! marches it front to back at `steps_per_voxel` samples per voxel length, descends the tree to
//! the drawn level at each sample and composites the node's extinction and emitted colour until
//! the transmittance falls below `10⁻⁴` (docs/design.md §8). Those two depend on the view
//! direction only: the host computes them per draw with the library
//! (`Octree::node_shading`, one reflectance per node) and uploads 16 bytes per node; the tree's
//! links are uploaded once (4 bytes per node). Per fragment the samples marched are read back
//! ([`OctreeFrame`]).

use std::time::Instant;

use altrep::ellipsoid::Octree;
use altrep::ellipsoid::octree::{OctreeRenderParams, OctreeView};
use altrep_data_gen::RgbaImage;

use crate::offscreen::{self, Pipeline, storage};
use crate::shader::{Precision, Shader};
use crate::{DisplayError, Gpu, invalid};

/// One drawn frame read back from the GPU.
#[derive(Clone, Debug)]
pub struct OctreeFrame {
    /// Premultiplied linear RGBA.
    pub image: RgbaImage,
    /// Per fragment (row-major): samples marched (0 where the ray misses the cube).
    pub steps: Vec<u32>,
    /// Wall time of the draw and read-back, the host's shading included (milliseconds; on
    /// lavapipe this is CPU emulation).
    pub millis: f64,
}

/// An octree uploaded to the GPU, with the pipeline that draws it.
pub struct OctreeDisplay {
    pipeline: std::sync::Arc<Pipeline>,
    tree: Octree,
    children: wgpu::Buffer,
}

impl OctreeDisplay {
    /// Uploads the tree's links and builds the pipeline. Cost: one pass over the nodes.
    ///
    /// Errors: nodes beyond the device's storage-buffer limit; a shader or pipeline the device
    /// rejects ([`DisplayError::Gpu`]).
    pub fn new(gpu: &Gpu, tree: &Octree) -> Result<Self, DisplayError> {
        let pipeline = offscreen::pipeline(gpu, Shader::Octree, Precision::F32)?;
        let nodes = tree.nodes().len();
        if (nodes * 16) as u64 > gpu.device.limits().max_storage_buffer_binding_size {
            return Err(invalid(
                "octree",
                format!("{nodes} nodes"),
                "exceed the device's storage-buffer size (16 bytes per node)",
            ));
        }
        let links: Vec<u32> = tree
            .nodes()
            .iter()
            .map(|n| n.first_child.map_or(0, |c| c.get()))
            .collect();
        Ok(Self {
            pipeline,
            children: storage(gpu, "octree links", bytemuck::cast_slice(&links)),
            tree: tree.clone(),
        })
    }

    /// The tree drawn.
    pub fn tree(&self) -> &Octree {
        &self.tree
    }

    /// Draws `view` at `level` (0: the leaves; at most the depth) with the shading of `params`,
    /// and reads back the image and the samples per fragment. Cost: one reflectance per node on
    /// the host, one draw of `width × height` fragments each marching its chord of the cube.
    ///
    /// Errors: a level above the depth, bad parameters or view (the library's checks), an image
    /// larger than 8192², a GPU error.
    pub fn render(
        &self,
        gpu: &Gpu,
        level: u32,
        params: &OctreeRenderParams,
        view: &OctreeView,
    ) -> Result<OctreeFrame, DisplayError> {
        let t0 = Instant::now();
        let bad = |e: altrep::ellipsoid::EllipsoidError| {
            invalid(
                "view or parameters",
                e.to_string(),
                "rejected by the library",
            )
        };
        view.validate().map_err(bad)?;
        if level > self.tree.depth() {
            return Err(invalid("level", level, "must be at most the tree's depth"));
        }
        if view.width > 8192 || view.height > 8192 {
            return Err(invalid(
                "image size",
                format!("{}×{}", view.width, view.height),
                "must be at most 8192²",
            ));
        }
        if params.steps_per_voxel == 0 {
            return Err(invalid("steps per voxel", 0, "must be at least 1"));
        }
        let shading: Vec<[f32; 4]> = self
            .tree
            .node_shading(params, view.dir)
            .map_err(bad)?
            .into_iter()
            .map(|(s, e)| [s as f32, e[0] as f32, e[1] as f32, e[2] as f32])
            .collect();
        let side = (1u64 << self.tree.depth()) as f64;
        let scalars: Vec<f32> = [
            view.width as f64,
            view.centre[0],
            view.centre[1],
            view.centre[2],
            view.half_width,
            view.right[0],
            view.right[1],
            view.right[2],
            view.up[0],
            view.up[1],
            view.up[2],
            view.dir[0],
            view.dir[1],
            view.dir[2],
            side,
            1.0 / params.steps_per_voxel as f64,
            view.height as f64,
        ]
        .iter()
        .map(|&v| v as f32)
        .collect();
        let ints = [level, self.tree.depth()];
        let fbuf = storage(gpu, "octree scalars", bytemuck::cast_slice(&scalars));
        let ibuf = storage(gpu, "octree integers", bytemuck::cast_slice(&ints));
        let sbuf = storage(gpu, "octree shading", bytemuck::cast_slice(&shading));
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[&fbuf, &ibuf, &self.children, &sbuf],
            view.width * view.height,
            (view.width, view.height),
            t0,
        )?;
        Ok(OctreeFrame {
            image: drawn.image,
            steps: drawn.steps,
            millis: drawn.millis,
        })
    }
}

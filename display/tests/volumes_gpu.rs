//! The volume shaders against their CPU twins and against the ray-cast ground truth, on assets
//! written by the pipeline's writer and read back through the library's loader: the slices of an
//! object (`altrep::slices::render_object`, one sample per pixel), a tile's slices over a ground
//! patch (`altrep::slices::render_slices`) and the ellipsoid octree
//! (`Octree::render_view_counted`).
//!
//! Without a GPU adapter every test prints "skipped: no GPU adapter" and passes, except with
//! `CI=true`, where a missing adapter fails. No reference image is stored: the expected images
//! are computed by the CPU renderers at test time. On failure the actual, expected and difference
//! PNGs go to `target/tmp/display-failures/`.

mod slices {
    use std::path::Path;

    use altrep::metrics::psnr;
    use altrep::pipeline::{Lighting, Needs, Representation, Source};
    use altrep::slices::asset::{BOX_MIN, SlicesAsset, SlicesRepr, SlicesSpec};
    use altrep::slices::render_object;
    use altrep_data_gen::{Light, RgbaImage, Supersample, render_truth_frame, scene_shape};
    use altrep_display::slices::{SlicesDisplay, SlicesDraw};
    use approx::assert_abs_diff_eq;
    use glam::DVec3;

    use crate::common::{
        assert_floor, check_against_cpu, gpu, volume_directions, written_and_loaded,
    };

    /// Screen size of the checks.
    const SIZE: usize = 64;

    /// The needs the slices are built for: every azimuth, elevations up to straight above (all three
    /// axes), screen sizes 8 to 64 (merged levels down to one slice).
    fn needs() -> Needs {
        Needs {
            elevation_deg: [-30.0, 90.0],
            screen_px: [8.0, 64.0],
            lighting: Lighting::Baked,
            ..Needs::default()
        }
    }

    /// Builds the slices of `shape` as the pipeline does, writes them with the pipeline's writer
    /// and loads them back through [`load`].
    fn asset(shape: &str, dir: &Path) -> SlicesAsset {
        let s = scene_shape(shape).unwrap();
        let src = Source {
            name: shape,
            geometry: Some(&s),
            texture: None,
            tile: None,
            light: Light::default(),
            placement: None,
        };
        let spec = SlicesSpec::default();
        let (plan, dec) = SlicesRepr::plan(&spec, &needs(), &src).unwrap();
        assert!(plan.refused.is_none(), "{plan:?}");
        let (data, _) = SlicesRepr::build(&spec, &needs(), &dec, &src).unwrap();
        written_and_loaded::<SlicesRepr>(dir, shape, &data)
    }

    /// Floors against the ray-cast truth (PSNR of the GPU image at 64², the stack the library
    /// chooses, averaged over [`directions`]).
    const FLOORS: [(&str, f64); 2] = [("tree", 29.26), ("chair", 28.22)];

    /// GPU vs CPU at two screen sizes (64 and 16 px: full and merged levels): every image at least
    /// 40 dB from the CPU's (worst printed; 134 dB measured), the same pixels covered, the slices
    /// read in all within 0.05 % of the CPU's (0.008 % measured), and per pixel equal but for at
    /// most 0.1 % of the pixels (0.055 % measured: in f32 against the CPU's f64, a ray's opacity
    /// can cross the early-termination threshold one slice earlier or later, or a ray within
    /// rounding of a slice plane at the box's face can cross one slice more or less). The GPU images
    /// at 64² score at least their floors against the object's ray-cast truth.
    #[test]
    fn gpu_slices_match_the_cpu_and_the_truth() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let (mut differ, mut total, mut gpu_sum, mut cpu_sum) = (0usize, 0usize, 0u64, 0u64);
        let mut worst_db = f64::INFINITY;
        let mut levels = Vec::new();
        for shape in ["tree", "chair"] {
            let a = asset(shape, dir.path());
            let disp = SlicesDisplay::new(gpu, &a).unwrap();
            let s = scene_shape(shape).unwrap();
            let mut truth_db = 0.0;
            for size in [SIZE, 16] {
                for d in volume_directions() {
                    let draw = SlicesDraw::new(d, size).unwrap();
                    let frame = disp.render(gpu, &draw).unwrap();
                    levels.push(frame.stack.1);
                    let want = render_object(
                        &a.slices,
                        frame.stack,
                        &draw.frame,
                        DVec3::from_array(BOX_MIN),
                        (size, size),
                        Supersample::ONE,
                    )
                    .unwrap();
                    let name = format!("slices-{shape}-{size}-{:.2}-{:.2}-{:.2}", d.x, d.y, d.z);
                    let db = check_against_cpu(&name, &frame.image, &want.image, 40.0, 0.01);
                    worst_db = worst_db.min(db);
                    assert_eq!(frame.covered, want.covered, "{name}: pixels covered");
                    for (g, c) in frame.steps.iter().zip(&want.steps) {
                        total += 1;
                        differ += usize::from(g != c);
                        gpu_sum += u64::from(*g);
                        cpu_sum += u64::from(*c);
                    }
                    assert_abs_diff_eq!(
                        frame.steps_per_pixel(),
                        want.steps_per_pixel,
                        epsilon = 5e-4 * want.steps_per_pixel
                    );
                    if size == SIZE {
                        let truth = render_truth_frame(
                            &s,
                            &draw.frame,
                            SIZE,
                            SIZE,
                            Supersample::of(3),
                            &Light::default(),
                        )
                        .unwrap();
                        truth_db +=
                            psnr(&frame.image, &truth).unwrap() / volume_directions().len() as f64;
                    }
                }
            }
            eprintln!("{shape}: GPU against the ray-cast truth at {SIZE}²: {truth_db:.2} dB");
            assert_floor(&FLOORS, shape, truth_db);
        }
        eprintln!(
            "f32: {differ} of {total} pixels differ in slices read; slices read GPU {gpu_sum}, CPU {cpu_sum}; worst image PSNR GPU vs CPU {worst_db:.1} dB; levels drawn {levels:?}"
        );
        assert!(
            differ as f64 <= 1e-3 * total as f64,
            "slices read differ at {differ} of {total} pixels"
        );
        assert_abs_diff_eq!(
            gpu_sum as f64,
            cpu_sum as f64,
            epsilon = 5e-4 * cpu_sum as f64
        );
        // The test reaches merged levels.
        assert!(levels.iter().any(|l| *l >= 2), "{levels:?}");
    }

    /// Bad draws are typed errors naming what was wrong; nothing is drawn.
    #[test]
    fn bad_draws_are_refused() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let a = asset("chair", dir.path());
        let disp = SlicesDisplay::new(gpu, &a).unwrap();
        assert!(SlicesDraw::new(DVec3::ZERO, 8).is_err());
        let mut draw = SlicesDraw::new(DVec3::X, 0).unwrap();
        assert!(disp.render(gpu, &draw).is_err());
        draw.size = 8;
        draw.stack = Some((altrep::slices::Axis::X, 40));
        let err = disp.render(gpu, &draw).unwrap_err().to_string();
        assert!(err.contains("stack"), "{err}");
        draw.stack = None;
        draw.choose_px = f64::NAN;
        assert!(disp.render(gpu, &draw).is_err());
        // An object's slices draw one box, not a patch of tiles.
        draw.choose_px = 8.0;
        draw.patch = [2, 2];
        let err = disp.render(gpu, &draw).unwrap_err().to_string();
        assert!(err.contains("patch"), "{err}");
        let _: RgbaImage = disp
            .render(gpu, &SlicesDraw::new(DVec3::X, 8).unwrap())
            .unwrap()
            .image;
    }
}

/// A tile's slices over a ground patch (`altrep::slices::render_slices`).
mod tiles {
    use std::path::Path;

    use altrep::pipeline::{Lighting, Needs, Representation, Source};
    use altrep::slices::asset::{SlicesAsset, SlicesRepr, SlicesSpec};
    use altrep::slices::{
        SliceLighting, SliceRenderParams, StackView, TestTile, render_slices, test_tile_lit,
    };
    use altrep_data_gen::{Light, Supersample};
    use altrep_display::slices::{SlicesDisplay, SlicesDraw};

    use crate::common::{check_against_cpu, gpu, written_and_loaded};

    /// Screen size of the checks.
    const SIZE: usize = 64;

    /// A grass tile's slices as the pipeline builds them for a lawn seen from its normal to 80°,
    /// 8 to 64 pixels across a tile, written and loaded back.
    fn lawn(dir: &Path) -> SlicesAsset {
        let light = Light::default();
        let lighting = SliceLighting {
            direction: light.direction.to_array(),
            ambient: light.ambient,
        };
        let tile = test_tile_lit(TestTile::Grass, 32, 3, &lighting).unwrap();
        let needs = Needs {
            screen_px: [8.0, 64.0],
            grazing_deg: 80.0,
            lighting: Lighting::Baked,
            ..Needs::default()
        };
        let src = Source {
            name: "lawn",
            geometry: None,
            texture: None,
            tile: Some(&tile),
            light,
            placement: None,
        };
        let spec = SlicesSpec::default();
        let (plan, dec) = SlicesRepr::plan(&spec, &needs, &src).unwrap();
        assert!(plan.refused.is_none(), "{plan:?}");
        let (data, _) = SlicesRepr::build(&spec, &needs, &dec, &src).unwrap();
        written_and_loaded::<SlicesRepr>(dir, "lawn", &data)
    }

    /// GPU vs CPU over the unbounded patch, one sample per pixel, trilinear 2D reads, the stack
    /// the asset chooses: at 1 and 4 voxels per pixel (all slices and merged levels), from
    /// straight above to 78°, every image at least 40 dB from the CPU's (worst printed; 132.0 dB
    /// measured), p99 error at most 0.01.
    #[test]
    fn gpu_tile_slices_match_the_cpu_over_the_patch() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let a = lawn(dir.path());
        let disp = SlicesDisplay::new(gpu, &a).unwrap();
        let n = a.slices.dims()[0] as f64;
        let offset = [0.37, -0.21];
        let mut worst = f64::INFINITY;
        let mut drawn = Vec::new();
        for p in [1.0, 4.0] {
            for (polar, azimuth) in [(0.0, 0.0), (35.0, 30.0), (60.0, 200.0), (78.0, 115.0)] {
                let view = StackView::degrees(polar, azimuth);
                let c = a.choose(view.vector(), n / p).unwrap();
                let draw = SlicesDraw::over_tile(&a, &view, SIZE, p, offset).unwrap();
                let got = disp.render(gpu, &draw).unwrap();
                assert_eq!(got.stack, (c.axis, c.level));
                drawn.push(got.stack);
                let want = render_slices(
                    &a.slices,
                    c.axis,
                    c.level,
                    &view,
                    &SliceRenderParams {
                        width: SIZE,
                        height: SIZE,
                        pixel_voxels: p,
                        supersample: Supersample::ONE,
                        mip_2d: true,
                        offset,
                        ..SliceRenderParams::default()
                    },
                )
                .unwrap();
                let name = format!("tile-slices-{p}-{polar}-{azimuth}");
                worst = worst.min(check_against_cpu(&name, &got.image, &want, 40.0, 0.01));
                assert!(
                    got.covered.iter().all(|c| *c),
                    "{name}: every ray crosses the layer"
                );
            }
        }
        eprintln!("tile slices: worst image PSNR GPU vs CPU {worst:.1} dB; stacks drawn {drawn:?}");
        assert!(
            drawn.iter().any(|s| s.1 >= 2),
            "merged levels reached: {drawn:?}"
        );
        assert!(
            drawn.iter().any(|s| s.0 != altrep::slices::Axis::Y),
            "{drawn:?}"
        );
    }

    /// A bounded patch of 3 × 2 tiles seen straight down draws the unbounded patch's pixels over
    /// its footprint and nothing beyond it; an object's draw refuses a patch.
    #[test]
    fn a_bounded_patch_draws_its_tiles_and_nothing_else() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let a = lawn(dir.path());
        let disp = SlicesDisplay::new(gpu, &a).unwrap();
        let view = StackView::degrees(0.0, 0.0);
        let n = a.slices.dims()[0] as f64;
        let l = n * a.slices.voxel_size();
        // 4 tiles across the screen, centred on the patch's corner region.
        let over =
            SlicesDraw::over_tile(&a, &view, SIZE, 4.0 * n / SIZE as f64, [0.5 * l, 0.5 * l]);
        let over = over.unwrap();
        let f = over.frame;
        let draw = |patch| SlicesDraw { patch, ..over };
        let open = disp.render(gpu, &draw([0, 0])).unwrap();
        let patch = disp.render(gpu, &draw([3, 2])).unwrap();
        let (mut inside, mut outside) = (0, 0);
        for j in 0..SIZE {
            for i in 0..SIZE {
                let x = f.centre
                    + f.radius
                        * ((-1.0 + (i as f64 + 0.5) * 2.0 / SIZE as f64) * f.right
                            + (1.0 - (j as f64 + 0.5) * 2.0 / SIZE as f64) * f.up);
                let k = j * SIZE + i;
                let within = |q: f64, tiles: f64| q > 1e-6 && q < tiles * l - 1e-6;
                if within(x.x, 3.0) && within(x.z, 2.0) {
                    inside += 1;
                    assert_eq!(
                        patch.image.pixels[k], open.image.pixels[k],
                        "pixel {i}, {j}"
                    );
                } else if x.x < -1e-6 || x.x > 3.0 * l + 1e-6 || x.z < -1e-6 || x.z > 2.0 * l + 1e-6
                {
                    outside += 1;
                    assert_eq!(patch.image.pixels[k], [0.0; 4], "pixel {i}, {j}");
                    assert!(!patch.covered[k]);
                }
            }
        }
        assert!(
            inside > 1000 && outside > 1000,
            "{inside} inside, {outside} outside"
        );
    }
}

mod octree {
    use std::path::Path;

    use altrep::ellipsoid::Octree;
    use altrep::ellipsoid::asset::{OctreeRepr, OctreeSpec};
    use altrep::ellipsoid::octree::{OctreeRenderParams, OctreeView};
    use altrep::metrics::psnr;
    use altrep::pipeline::{Needs, Representation, Source};
    use altrep_data_gen::{Light, OrthoFrame, Supersample, render_truth_frame, scene_shape};
    use altrep_display::octree::OctreeDisplay;
    use approx::assert_abs_diff_eq;
    use glam::DVec3;

    use crate::common::{
        assert_floor, check_against_cpu, gpu, volume_directions, written_and_loaded,
    };

    /// Leaves per side of the trees, and the screen size of the checks (one pixel per leaf).
    const SIZE: usize = 32;

    /// Builds the octree of `shape` as the pipeline does, writes it with the pipeline's writer and
    /// loads it back through [`load`].
    fn asset(shape: &str, dir: &Path) -> Octree {
        let s = scene_shape(shape).unwrap();
        let src = Source {
            name: shape,
            geometry: Some(&s),
            texture: None,
            tile: None,
            light: Light::default(),
            placement: None,
        };
        let spec = OctreeSpec {
            resolution: SIZE,
            ..OctreeSpec::default()
        };
        let needs = Needs::default();
        let (_, dec) = OctreeRepr::plan(&spec, &needs, &src).unwrap();
        let (data, _) = OctreeRepr::build(&spec, &needs, &dec, &src).unwrap();
        written_and_loaded::<OctreeRepr>(dir, shape, &data)
    }

    /// The frame over the bounding cylinder's window along `dir` and the same view of the tree's
    /// cube (the box `[−1, 1] × [0, 2] × [−1, 1]` scaled to `[0, 2^depth]³`), `size²` pixels.
    fn views(tree: &Octree, dir: DVec3, size: usize) -> (OrthoFrame, OctreeView) {
        let frame = OrthoFrame::new(DVec3::Y, 1.0, dir).unwrap();
        let half = 0.5 * (1u64 << tree.depth()) as f64;
        let view = OctreeView {
            dir: frame.dir.to_array(),
            right: frame.right.to_array(),
            up: frame.up.to_array(),
            centre: [half; 3],
            half_width: half * frame.radius,
            width: size,
            height: size,
        };
        (frame, view)
    }

    /// Floors against the ray-cast truth (PSNR of the GPU image of level 0 at 32², averaged over
    /// [`directions`]).
    const FLOORS: [(&str, f64); 2] = [("tree", 24.67), ("chair", 24.37)];

    /// GPU vs CPU at levels 0, 1 and 2 (32² px): every image at least 40 dB from the CPU's (worst
    /// printed; 141.7 dB measured), the samples marched per fragment equal but for at most 0.1 % of
    /// the fragments and within 0.05 % in all (f32 against the CPU's f64: a transmittance crossing
    /// 10⁻⁴ one sample earlier or later; none differs as measured). The GPU images of level 0 score at least their floors against the
    /// object's ray-cast truth.
    #[test]
    fn gpu_octree_matches_the_cpu_and_the_truth() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let params = OctreeRenderParams::default();
        let (mut differ, mut total, mut gpu_sum, mut cpu_sum) = (0usize, 0usize, 0u64, 0u64);
        let mut worst_db = f64::INFINITY;
        for shape in ["tree", "chair"] {
            let tree = asset(shape, dir.path());
            let disp = OctreeDisplay::new(gpu, &tree).unwrap();
            let s = scene_shape(shape).unwrap();
            let mut truth_db = 0.0;
            for d in volume_directions() {
                let (frame, view) = views(&tree, d, SIZE);
                for level in 0..3 {
                    let got = disp.render(gpu, level, &params, &view).unwrap();
                    let (want, steps) = tree.render_view_counted(level, &params, &view).unwrap();
                    let name = format!("octree-{shape}-{level}-{:.2}-{:.2}-{:.2}", d.x, d.y, d.z);
                    let db = check_against_cpu(&name, &got.image, &want, 40.0, 0.01);
                    worst_db = worst_db.min(db);
                    for (g, c) in got.steps.iter().zip(&steps) {
                        total += 1;
                        differ += usize::from(g != c);
                        gpu_sum += u64::from(*g);
                        cpu_sum += u64::from(*c);
                    }
                    if level == 0 {
                        let truth = render_truth_frame(
                            &s,
                            &frame,
                            SIZE,
                            SIZE,
                            Supersample::of(3),
                            &Light::default(),
                        )
                        .unwrap();
                        truth_db +=
                            psnr(&got.image, &truth).unwrap() / volume_directions().len() as f64;
                    }
                }
            }
            eprintln!(
                "{shape}: GPU level 0 against the ray-cast truth at {SIZE}²: {truth_db:.2} dB"
            );
            assert_floor(&FLOORS, shape, truth_db);
        }
        eprintln!(
            "f32: {differ} of {total} fragments differ in samples marched; GPU {gpu_sum}, CPU {cpu_sum}; worst image PSNR GPU vs CPU {worst_db:.1} dB"
        );
        assert!(
            differ as f64 <= 1e-3 * total as f64,
            "samples differ at {differ} of {total} fragments"
        );
        assert_abs_diff_eq!(
            gpu_sum as f64,
            cpu_sum as f64,
            epsilon = 5e-4 * cpu_sum as f64
        );
    }

    /// Bad draws are typed errors naming what was wrong.
    #[test]
    fn bad_octree_draws_are_refused() {
        let Some(gpu) = gpu() else { return };
        let dir = tempfile::tempdir().unwrap();
        let tree = asset("chair", dir.path());
        let disp = OctreeDisplay::new(gpu, &tree).unwrap();
        let params = OctreeRenderParams::default();
        let (_, view) = views(&tree, DVec3::X, 8);
        let err = disp.render(gpu, 9, &params, &view).unwrap_err().to_string();
        assert!(err.contains("level"), "{err}");
        let mut skew = view;
        skew.right = [1.0, 1.0, 0.0];
        assert!(disp.render(gpu, 0, &params, &skew).is_err());
        let dark = OctreeRenderParams {
            tau: f64::NAN,
            ..params
        };
        assert!(disp.render(gpu, 0, &dark, &view).is_err());
        let none = OctreeRenderParams {
            steps_per_voxel: 0,
            ..params
        };
        assert!(disp.render(gpu, 0, &none, &view).is_err());
    }
}

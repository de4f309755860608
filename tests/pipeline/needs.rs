//! Every need of the manifest's `[asset.needs]` changes what is built or measured: the views off
//! the horizontal (refused with the representation that holds them named, or measured there),
//! and one comparison of two values for each need.

use super::*;
use altrep::pipeline::Measurement;
use altrep::representation::Plan;
use altrep::sphere::asset::{SphereRepr, SphereSpec};

/// Plans `R` for `needs`, then builds and measures it unless the plan refuses it.
fn measured<R: Representation>(
    spec: &R::Spec,
    needs: &Needs,
    src: &Source,
) -> (Plan, Option<Measurement>) {
    let (plan, dec) = R::plan(spec, needs, src).unwrap();
    if plan.refused.is_some() {
        return (plan, None);
    }
    let (data, _) = R::build(spec, needs, &dec, src).unwrap();
    let (m, _) = R::measure(&data, needs, R::measure_size(&dec), src).unwrap();
    (plan, Some(m))
}

fn needs(elevation_deg: [f64; 2], quality_db: f64) -> Needs {
    Needs {
        elevation_deg,
        screen_px: [4.0, 32.0],
        quality_db,
        ..Needs::default()
    }
}

/// Views from above: representations holding horizontal views only (images with parallax, the
/// cylindrical texture) are refused, naming the frames over the sphere, when the object seen from
/// the needed elevation differs from its horizontal view by more than the quality target allows;
/// within it they are built and measured at the needed elevations, where they measure worse than
/// at the horizontal. The octree holds every direction: measured against the ray-cast truth from
/// 20° to 90° it stays within 3 dB of its horizontal figure, at 20 dB or more.
#[test]
fn views_off_the_horizontal_are_refused_or_measured_where_they_are_needed() {
    let chair = scene_shape("chair").unwrap();
    let src = source("chair", &chair);
    let above = needs([20.0, 90.0], 20.0);
    for (repr, plan) in [
        (
            "parallax",
            Parallax::plan(&ParallaxSpec::default(), &above, &src)
                .unwrap()
                .0,
        ),
        (
            "cylinder",
            Cylinder::plan(&CylinderSpec::default(), &above, &src)
                .unwrap()
                .0,
        ),
    ] {
        let reason = plan
            .refused
            .unwrap_or_else(|| panic!("{repr} kept: {:?}", plan.items));
        assert!(
            reason.contains("[asset.sphere]") && reason.contains("90°"),
            "{reason}"
        );
    }
    let (plan, dec) = SphereRepr::plan(&SphereSpec::default(), &above, &src).unwrap();
    assert!(plan.refused.is_none());
    assert_eq!(dec.coverage, altrep::sphere::Coverage::Hemisphere);

    let pear = scene_shape("pear").unwrap();
    let src = source("pear", &pear);
    let flat = needs([0.0, 0.0], 15.0);
    let low = needs([0.0, 10.0], 15.0);
    let (_, at0) = measured::<Parallax>(&ParallaxSpec::default(), &flat, &src);
    let (plan, at10) = measured::<Parallax>(&ParallaxSpec::default(), &low, &src);
    let (at0, at10) = (at0.unwrap(), at10.unwrap());
    assert!(
        plan.items
            .iter()
            .any(|i| i.what.contains("0° to 10° of elevation")),
        "{:?}",
        plan.items
    );
    eprintln!(
        "pear parallax: {:.2} dB (worst {:.2}) at 0°; {:.2} dB (worst {:.2}) over 0–10°",
        at0.psnr_db, at0.worst_psnr_db, at10.psnr_db, at10.worst_psnr_db
    );
    assert!(
        at10.method.contains("elevations 0° to 10°"),
        "{}",
        at10.method
    );
    assert!(at10.worst_psnr_db < at0.worst_psnr_db, "{at0:?} {at10:?}");
    // The same asset at 30° is kept for a 15 dB target and refused for 30 dB.
    let steep = |q| {
        Cylinder::plan(&CylinderSpec::default(), &needs([0.0, 30.0], q), &src)
            .unwrap()
            .0
    };
    assert!(steep(15.0).refused.is_none());
    assert!(steep(30.0).refused.is_some());

    let spec = OctreeSpec::default();
    let (_, horizontal) = measured::<OctreeRepr>(&spec, &needs([0.0, 0.0], 0.0), &src);
    let (_, from_above) = measured::<OctreeRepr>(&spec, &above, &src);
    let (h, a) = (horizontal.unwrap(), from_above.unwrap());
    eprintln!(
        "pear octree: {:.2} dB (worst {:.2}) at 0°; {:.2} dB (worst {:.2}) over 20–90°",
        h.psnr_db, h.worst_psnr_db, a.psnr_db, a.worst_psnr_db
    );
    assert!(a.method.contains("elevations 20° to 90°"), "{}", a.method);
    assert!(h.psnr_db >= 20.0 && a.worst_psnr_db >= 20.0, "{h:?} {a:?}");
    assert_abs_diff_eq!(h.psnr_db, a.psnr_db, epsilon = 3.0);
}

/// One comparison per need: two values of it change a decision of the planner or the measured
/// figures. `quality_db` also gates the run (see `a_representation_below_its_quality_target_is_
/// flagged_and_fails_the_run`); `grazing_deg` chooses the pyramid's kind (see
/// `pyramid_files_read_back_bit_for_bit_and_measure_well`) and is checked again here.
#[test]
fn every_need_changes_what_is_built_or_measured() {
    let tree = scene_shape("tree").unwrap();
    let src = source("tree", &tree);
    let base = needs([0.0, 0.0], 20.0);
    let with = |f: &dyn Fn(&mut Needs)| {
        let mut n = base.clone();
        f(&mut n);
        n
    };
    let pplan = |n: &Needs| Parallax::plan(&ParallaxSpec::default(), n, &src).unwrap();
    let cplan = |n: &Needs| Cylinder::plan(&CylinderSpec::default(), n, &src).unwrap();
    let oplan = |n: &Needs| OctreeRepr::plan(&OctreeSpec::default(), n, &src).unwrap();
    let splan = |n: &Needs| SphereRepr::plan(&SphereSpec::default(), n, &src).unwrap();

    // azimuth_deg: the parallax views kept, and where the octree is measured.
    let narrow = with(&|n| n.azimuth_deg = [80.0, 100.0]);
    assert_ne!(pplan(&base).1.views, pplan(&narrow).1.views);
    let spec = OctreeSpec {
        resolution: 16,
        ..OctreeSpec::default()
    };
    let (_, m0) = measured::<OctreeRepr>(&spec, &base, &src);
    let (_, m1) = measured::<OctreeRepr>(&spec, &narrow, &src);
    assert_ne!(m0.unwrap().psnr_db, m1.unwrap().psnr_db);
    // elevation_deg: the sphere's frames below the horizon, the parallax plan.
    let below = with(&|n| n.elevation_deg = [-30.0, 0.0]);
    assert_ne!(splan(&base).1.coverage, splan(&below).1.coverage);
    assert_ne!(pplan(&base).0, pplan(&below).0);
    // screen_px: every size.
    let small = with(&|n| n.screen_px = [2.0, 8.0]);
    assert_ne!(pplan(&base).1.size, pplan(&small).1.size);
    assert_ne!(cplan(&base).1.rows, cplan(&small).1.rows);
    assert_ne!(oplan(&base).1.resolution, oplan(&small).1.resolution);
    assert_ne!(splan(&base).1.size, splan(&small).1.size);
    // lighting: normals stored or not.
    let baked = with(&|n| n.lighting = Lighting::Baked);
    assert_ne!(pplan(&base).1.normals, pplan(&baked).1.normals);
    assert_ne!(cplan(&base).1.normals, cplan(&baked).1.normals);
    // quality_db: whether a horizontal-only representation serves 15° of elevation.
    let tilted = |q: f64| with(&|n| (n.elevation_deg, n.quality_db) = ([0.0, 15.0], q));
    assert_ne!(
        pplan(&tilted(10.0)).0.refused.is_some(),
        pplan(&tilted(40.0)).0.refused.is_some()
    );
    // grazing_deg: the pyramid's kind.
    let tex = altrep::pyramid::truth::test_texture(32, 1);
    let tsrc = texture_source(&tex);
    let kind = |g: f64| {
        PyramidRepr::plan(
            &PyramidParams::default(),
            &with(&|n| n.grazing_deg = g),
            &tsrc,
        )
        .unwrap()
        .1
        .kind
    };
    assert_ne!(kind(20.0), kind(85.0));
}

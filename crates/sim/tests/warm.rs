//! Warm starts judged against the simulators' truth: frames of a moving shape and of a
//! drawing, through the library's public API.

use isoline_core::{
    geom::add, reconstruct, reconstruct_warm, ExportParams, MeshParams, Params, Point,
    Reconstruction, SolverParams,
};
use isoline_sim::{generate, Shape, SynthParams};

fn stream() -> Vec<isoline_sim::SynthFrame> {
    let mut p = SynthParams::new(Shape::Ellipse);
    p.points = 1000;
    p.noise = 0.003;
    p.frames = 4;
    p.motion = 0.003;
    p.seed = 3;
    generate(&p).unwrap()
}

fn hausdorff(r: &Reconstruction, truth: &[isoline_core::Polyline]) -> f64 {
    isoline_sim::compare(&r.polylines, truth, None)
        .hausdorff
        .unwrap()
}

/// A drawing of strokes encloses nothing: its frames come out as strokes, and the
/// next frame does not warm-start from the box's loop round the drawing (which would
/// come back as a loop).
#[test]
fn strokes_are_not_warm_started_from_the_loop_round_them() {
    let mut p = SynthParams::new(Shape::Strokes);
    p.noise = 0.002;
    p.frames = 2;
    p.seed = 7;
    let frames = generate(&p).unwrap();
    let params = Params::default();
    let first = reconstruct(&frames[0].points, &params).unwrap();
    assert!(!first.enclosed && first.polylines.iter().all(|l| !l.closed));
    let next = reconstruct_warm(&frames[1].points, &params, Some(&first)).unwrap();
    assert!(!next.stats.warm_start);
    assert!(!next.polylines.is_empty() && next.polylines.iter().all(|l| !l.closed));
    assert_eq!(next.junctions().len(), 3);
}

/// Warm frames meet the one-shot bound 3 sigma + 2 hmin, and so does a frame after a
/// jump of 40 hmin (far beyond the mesh's fine band, within its domain): its level set
/// starts cold, and its mesh, adapted from the old one, is about as fine as a cold
/// frame's.
#[test]
fn warm_frames_and_a_jump_stay_within_the_one_shot_bound() {
    let frames = stream();
    let params = Params::new(
        MeshParams::default().with_hmin(0.002),
        SolverParams::default(),
        ExportParams::default(),
    );
    let bound = 3.0 * 0.003 + 2.0 * 0.002;
    let mut prev = reconstruct(&frames[0].points, &params).unwrap();
    for f in &frames[1..] {
        let r = reconstruct_warm(&f.points, &params, Some(&prev)).unwrap();
        assert!(r.stats.warm_start, "frame {}", f.frame);
        let h = hausdorff(&r, &f.truth);
        assert!(h <= bound, "frame {}: {h} > {bound}", f.frame);
        prev = r;
    }
    let jump = [0.08, 0.0];
    let last = frames.last().unwrap();
    let moved: Vec<Point> = last.points.iter().map(|&p| add(p, jump)).collect();
    let mut truth = last.truth.clone();
    truth
        .iter_mut()
        .flat_map(|pl| pl.points.iter_mut())
        .for_each(|p| *p = add(*p, jump));
    let r = reconstruct_warm(&moved, &params, Some(&prev)).unwrap();
    assert!(!r.stats.warm_start);
    let h = hausdorff(&r, &truth);
    assert!(h <= bound, "after the jump: {h} > {bound}");
    let cold = reconstruct(&moved, &params).unwrap();
    let ratio = r.stats.vertices as f64 / cold.stats.vertices as f64;
    assert!(
        (0.8..1.25).contains(&ratio),
        "{} vs {} cold",
        r.stats.vertices,
        cold.stats.vertices
    );
}

//! Benchmarks of reconstruction: the cold `reconstruct` of the noisy circle
//! (2,000 points, sigma 0.002) with each scheme's stages, one renormalization of its
//! level set by fast marching, and a cold reconstruct of 20,000 points (how time grows
//! with the number of points; 200,000 points are timed in the README); and one frame of
//! the README's daemon stream (moving ellipse, 1,000 points, sigma 0.003, hmin 0.002),
//! warm-started from the frame before it and cold; and one 1,080-beam scan of the
//! simulated room (Hokuyo UTM-30LX-like, range noise 1 cm, 2% dropout, a static sensor),
//! warm (its mesh adapted from the frame before it) and cold.

use criterion::{criterion_group, criterion_main, Criterion};
use isoline_core::{
    reconstruct, reconstruct_warm, stages, ExportParams, MeshParams, Params, SolverParams,
};
use isoline_sim::{generate, Shape, SynthParams};

fn circle(points: usize, noise: f64) -> Vec<[f64; 2]> {
    let mut p = SynthParams::new(Shape::Circle);
    p.points = points;
    p.noise = noise;
    generate(&p).unwrap().remove(0).points
}

fn cold(c: &mut Criterion) {
    let mut g = c.benchmark_group("reconstruct");
    g.sample_size(10);
    let pts = circle(2000, 0.002);
    g.bench_function("circle_2000_noisy_semi_implicit", |b| {
        b.iter(|| {
            reconstruct(&pts, &Params::default())
                .unwrap()
                .stats
                .iterations
        })
    });
    let pts = circle(20_000, 0.002);
    g.bench_function("circle_20000_noisy_semi_implicit", |b| {
        b.iter(|| {
            reconstruct(&pts, &Params::default())
                .unwrap()
                .stats
                .iterations
        })
    });
    g.finish();
}

fn renormalize(c: &mut Criterion) {
    let pts = circle(2000, 0.002);
    let r = reconstruct(&pts, &Params::default()).unwrap();
    // A level set with the right zero isoline but |grad u| = 3 everywhere.
    let distorted: Vec<f64> = r.u.iter().map(|u| 3.0 * u).collect();
    let mut u = distorted.clone();
    c.bench_function("fast_marching_full_mesh", |b| {
        b.iter(|| {
            u.copy_from_slice(&distorted);
            stages::redistance(&r.mesh, &mut u);
            u[0]
        })
    });
    println!(
        "fast marching: {} vertices, {} triangles",
        r.mesh.num_vertices(),
        r.mesh.num_triangles()
    );
}

fn stream_frame(c: &mut Criterion) {
    let mut p = SynthParams::new(Shape::Ellipse);
    p.points = 1000;
    p.noise = 0.003;
    p.frames = 2;
    p.motion = 0.003;
    p.seed = 8;
    let frames = generate(&p).unwrap();
    let params = Params::new(
        MeshParams::default().with_hmin(0.002),
        SolverParams::default(),
        ExportParams::default(),
    );
    let first = reconstruct(&frames[0].points, &params).unwrap();
    let next = &frames[1].points;
    assert!(
        reconstruct_warm(next, &params, Some(&first))
            .unwrap()
            .stats
            .warm_start
    );
    let mut g = c.benchmark_group("stream_frame");
    g.sample_size(20);
    g.bench_function("ellipse_1000_warm", |b| {
        b.iter(|| {
            reconstruct_warm(next, &params, Some(&first))
                .unwrap()
                .stats
                .iterations
        })
    });
    g.bench_function("ellipse_1000_cold", |b| {
        b.iter(|| reconstruct(next, &params).unwrap().stats.iterations)
    });
    g.finish();
}

fn scan_frame(c: &mut Criterion) {
    use isoline_core::stages::reconstruct_with;
    use isoline_core::{LaserScan, Scan};
    use isoline_sim::lidar::{simulate, LidarParams, SceneKind};
    let mut p = LidarParams::new(SceneKind::Room);
    p.noise = Some(0.01);
    p.dropout = 0.02;
    p.frames = 2;
    let scans: Vec<Scan> = simulate(&p)
        .unwrap()
        .iter()
        .map(|f| {
            Scan::from_laser(&LaserScan {
                origin: [0.0, 0.0],
                angle_min: f.angle_min,
                angle_increment: f.angle_increment,
                ranges: &f.ranges,
                range_min: f.range_min,
                range_max: f.range_max,
            })
            .unwrap()
        })
        .collect();
    assert_eq!(scans[1].angles.len(), 1080);
    let params = Params::default();
    let run = |s: &Scan, prev| reconstruct_with(&s.returns(), Some(s), &params, prev).unwrap();
    let first = run(&scans[0], None);
    // A scan frame is built from its own scan, warm stream or not.
    assert_eq!(
        run(&scans[1], Some(&first)).stats.start,
        isoline_core::Start::Scan
    );
    let mut g = c.benchmark_group("scan_frame");
    g.sample_size(20);
    g.bench_function("room_1080_beams_warm", |b| {
        b.iter(|| run(&scans[1], Some(&first)).stats.vertices)
    });
    g.bench_function("room_1080_beams_cold", |b| {
        b.iter(|| run(&scans[1], None).stats.vertices)
    });
    g.finish();
}

criterion_group!(benches, cold, renormalize, stream_frame, scan_frame);
criterion_main!(benches);

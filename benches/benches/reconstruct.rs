//! Benchmarks of reconstruction: the cold `reconstruct` of the noisy circle
//! (2,000 points, sigma 0.002) with each scheme's stages, one renormalization of its
//! level set by fast marching, and a cold reconstruct of 20,000 points (how time grows
//! with the number of points; 200,000 points are timed in docs/benchmarks.md); and one frame of
//! the README's daemon stream (moving ellipse, 1,000 points, sigma 0.003, hmin 0.002),
//! warm-started from the frame before it and cold. Scan frames are benched in
//! isoline-io's `scans` bench, beside a line extractor.

use criterion::{criterion_group, criterion_main, Criterion};
use isoline_bench::circle;
use isoline_core::{
    reconstruct, reconstruct_warm, stages, ExportParams, MeshParams, Params, SolverParams,
};
use isoline_sim::{generate, Shape, SynthParams};

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

criterion_group!(benches, cold, renormalize, stream_frame);
criterion_main!(benches);

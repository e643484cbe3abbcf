//! Benchmarks of the foundation stages: kd-tree build and distances at 100k vertices,
//! one full adaptation of the noisy circle, and the Hausdorff distance between two
//! 100k-vertex polylines. Data come from `isoline_sim`, the generator the tests use.

use criterion::{criterion_group, criterion_main, Criterion};
use isoline_bench::circle;
use isoline_core::DistanceField;
use isoline_core::{stages::adapt_to_points, MeshParams};
use rand::{Rng, SeedableRng};

fn distance(c: &mut Criterion) {
    let pts = circle(2000, 0.002);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    // Query points concentrated near the data, as an adapted mesh's vertices are.
    let queries: Vec<[f64; 2]> = (0..100_000)
        .map(|i| {
            let a: f64 = rng.random::<f64>() * std::f64::consts::TAU;
            let r = if i % 4 == 0 {
                rng.random::<f64>() * 0.6
            } else {
                0.4 + 0.02 * (rng.random::<f64>() - 0.5)
            };
            [0.5 + r * a.cos(), 0.5 + r * a.sin()]
        })
        .collect();
    let mut out = Vec::new();
    c.bench_function("kdtree_build_and_distance_100k_vertices", |b| {
        b.iter(|| {
            let field = DistanceField::new(&pts).unwrap();
            field.distances_into(&queries, &mut out);
            out[0]
        })
    });
}

fn adaptation(c: &mut Criterion) {
    let pts = circle(2000, 0.002);
    let params = MeshParams::default().with_hmin(1e-3).with_eps(1e-3);
    let mut g = c.benchmark_group("adapt");
    g.sample_size(10);
    g.bench_function("circle_2000pts_hmin1e-3_anisotropic", |b| {
        b.iter(|| adapt_to_points(&pts, &params).unwrap().stats.vertices)
    });
    g.finish();
}

fn evaluation(c: &mut Criterion) {
    use isoline_core::geom::Polyline;
    let ring = |r: f64, n: usize, phase: f64| Polyline {
        closed: true,
        points: (0..n)
            .map(|i| {
                let a = phase + std::f64::consts::TAU * i as f64 / n as f64;
                [0.5 + r * a.cos(), 0.5 + r * a.sin()]
            })
            .collect(),
    };
    let recon = [ring(0.401, 100_000, 0.3)];
    let truth = [ring(0.4, 100_000, 0.0)];
    let mut g = c.benchmark_group("eval");
    g.sample_size(10);
    g.bench_function("hausdorff_100k_vs_100k_vertices", |b| {
        b.iter(|| isoline_sim::compare(&recon, &truth, None).hausdorff)
    });
    g.finish();
}

criterion_group!(benches, distance, adaptation, evaluation);
criterion_main!(benches);

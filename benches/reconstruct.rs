//! Benchmarks of reconstruction: the cold `reconstruct` of the noisy circle
//! (2,000 points, sigma 0.002) with each scheme's stages, one renormalization of its
//! level set by fast marching, and a cold reconstruct of 20,000 points (how time grows
//! with the number of points; 200,000 points are timed in the README).

use criterion::{criterion_group, criterion_main, Criterion};
use isoline::fem::P1Space;
use isoline::reconstruct::{reconstruct, Params};
use isoline::redistance::Redistancer;
use isoline::synth::{generate, Shape, SynthParams};

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
    let space = P1Space::new(&r.mesh);
    // A level set with the right zero isoline but |grad u| = 3 everywhere.
    let distorted: Vec<f64> = r.u.iter().map(|u| 3.0 * u).collect();
    let mut u = distorted.clone();
    let mut fm = Redistancer::new();
    c.bench_function("fast_marching_full_mesh", |b| {
        b.iter(|| {
            u.copy_from_slice(&distorted);
            fm.run(&r.mesh, &space, &mut u, f64::INFINITY)
        })
    });
    println!(
        "fast marching: {} vertices, {} triangles",
        r.mesh.num_vertices(),
        r.mesh.num_triangles()
    );
}

criterion_group!(benches, cold, renormalize);
criterion_main!(benches);

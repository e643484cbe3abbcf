//! Benchmarks of mapping's two solvers.
//!
//! The scan-to-map registration: a simulated SICK-like scan of the clutter scene laid
//! onto the surface of the five scans before it (placed by their true poses), started
//! 20 cm and 3 degrees off with the odometry's prior, as the map's registration does
//! each scan.
//!
//! The pose graph's solve: a robot that drives four laps of a 20 x 10 m
//! corridor loop, a keyframe every half metre (480 nodes), each lap's keyframes tied by
//! loop edges to the first lap's at the same place, every edge measured with a
//! centimetre and a tenth of a degree of noise, solved from the odometry's drifted
//! chain (a degree of heading error a lap). The loops tie far-apart nodes again and
//! again, as a robot that keeps coming back does: the case a fill-reducing ordering is
//! for.

use criterion::{criterion_group, criterion_main, Criterion};
use isoline_core::geom::to_world;
use isoline_map::{between, compose, register_points, Edge, PoseGraph, Prior, Surface};
use isoline_sim::lidar::{simulate, LidarParams, SceneKind};
use nalgebra::Matrix3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

fn laps() -> PoseGraph {
    let lap: Vec<[f64; 3]> = {
        let mut v = Vec::new();
        let side = |from: [f64; 2], to: [f64; 2], heading: f64, v: &mut Vec<[f64; 3]>| {
            let n = ((to[0] - from[0]).hypot(to[1] - from[1]) / 0.5) as usize;
            for i in 0..n {
                let t = i as f64 / n as f64;
                v.push([
                    from[0] + t * (to[0] - from[0]),
                    from[1] + t * (to[1] - from[1]),
                    heading,
                ]);
            }
        };
        let h = std::f64::consts::FRAC_PI_2;
        side([0.0, 0.0], [20.0, 0.0], 0.0, &mut v);
        side([20.0, 0.0], [20.0, 10.0], h, &mut v);
        side([20.0, 10.0], [0.0, 10.0], 2.0 * h, &mut v);
        side([0.0, 10.0], [0.0, 0.0], -h, &mut v);
        v
    };
    let truth: Vec<[f64; 3]> = (0..4).flat_map(|_| lap.iter().copied()).collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (st, sr) = (0.01, 0.1f64.to_radians());
    let (nt, nr) = (Normal::new(0.0, st).unwrap(), Normal::new(0.0, sr).unwrap());
    let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(
        1.0 / (st * st),
        1.0 / (st * st),
        1.0 / (sr * sr),
    ));
    let mut measure = |a: [f64; 3], b: [f64; 3]| {
        let z = between(a, b);
        [
            z[0] + nt.sample(&mut rng),
            z[1] + nt.sample(&mut rng),
            z[2] + nr.sample(&mut rng),
        ]
    };
    let mut edges = Vec::new();
    let mut nodes = vec![truth[0]];
    let drift = (1.0f64 / lap.len() as f64).to_radians();
    for k in 1..truth.len() {
        let z = measure(truth[k - 1], truth[k]);
        edges.push(Edge {
            from: k - 1,
            to: k,
            z,
            info,
            loop_closure: false,
        });
        let last = *nodes.last().expect("the first node");
        nodes.push(compose(last, [z[0], z[1], z[2] + drift]));
    }
    for k in lap.len()..truth.len() {
        let j = k % lap.len();
        edges.push(Edge {
            from: j,
            to: k,
            z: measure(truth[j], truth[k]),
            info,
            loop_closure: true,
        });
    }
    PoseGraph { nodes, edges }
}

fn pose_graph(c: &mut Criterion) {
    let graph = laps();
    let mut g = c.benchmark_group("pose_graph");
    g.sample_size(20);
    g.bench_function("four_laps_480_nodes_360_loops", |b| {
        b.iter(|| {
            let mut solved = graph.clone();
            solved.optimize(20).map(|s| s.steps)
        })
    });
    g.finish();
}

fn scan_to_map(c: &mut Criterion) {
    let mut params = LidarParams::new(SceneKind::Clutter);
    params.frames = 6;
    params.motion = 0.3;
    let frames = simulate(&params).expect("valid parameters");
    let returns = |f: &isoline_sim::lidar::ScanFrame| -> Vec<[f64; 2]> {
        f.scan().expect("a valid scan").returns()
    };
    let (last, before) = frames.split_last().expect("six frames");
    let world: Vec<[f64; 2]> = before
        .iter()
        .flat_map(|f| returns(f).into_iter().map(|p| to_world(f.pose, p)))
        .collect();
    let target = Surface::new(&world, 0.3);
    let scan = returns(last);
    let truth = last.pose;
    let start = [truth[0] + 0.2, truth[1] - 0.1, truth[2] + 3f64.to_radians()];
    let prior = Prior {
        mean: start,
        info: Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 100.0, 400.0)),
    };
    // What is timed must be right: a thousand returns with centimetres of noise place
    // the scan to millimetres.
    let found = register_points(&scan, 1.0, &target, start, Some(&prior), 0.02, 0.5).pose;
    let off = between(truth, found);
    assert!(
        off[0].hypot(off[1]) < 0.01 && off[2].abs() < 0.2f64.to_radians(),
        "registered {off:?} off the truth"
    );
    let mut g = c.benchmark_group("scan_to_map");
    g.bench_function("clutter_scan_onto_five_scans", |b| {
        b.iter(|| register_points(&scan, 1.0, &target, start, Some(&prior), 0.02, 0.5).pose)
    });
    g.finish();
}

criterion_group!(benches, pose_graph, scan_to_map);
criterion_main!(benches);

//! CPU per scan frame, on one thread (the global rayon pool is built with one thread, so
//! that wall time is CPU time), beside a textbook split-and-merge line extractor timed
//! on the same frames in the same run:
//!
//! - real frames, when `ISOLINE_BENCH_SICK` names a CARMEN log (a 180-beam SICK LMS)
//!   and `ISOLINE_BENCH_HOKUYO` an NDJSON beam stream (a 683-beam Hokuyo URG-04LX):
//!   `scripts/bench-scans.sh` unpacks the recordings and sets both; without them these
//!   are skipped with a note;
//! - the simulator's 1,080-beam room frame (Hokuyo UTM-30LX-like, 1 cm noise, 2%
//!   dropout);
//! - the scaling: a round room seen from its centre by a full-turn scanner, 180 to
//!   4,000 returns at a radius of 4 m, and radii of 2 to 32 m at 1,080 returns (the
//!   scene's area must not matter).
//!
//! A scan frame is built from its own scan whether its stream is warm or not: the warm
//! case (the previous frame passed as the warm start) is timed to show it costs the same.

use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use isoline_core::stages::reconstruct_with;
use isoline_core::{LaserScan, Params, Scan};
use isoline_io::read_input;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A full-turn scan of `beams` beams from the centre of a round room of `radius` metres,
/// range noise 1 cm.
fn round_room(beams: usize, radius: f64, seed: u64) -> Scan {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let ranges: Vec<Option<f64>> = (0..beams)
        .map(|_| Some(radius + noise.sample(&mut rng)))
        .collect();
    Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: 0.0,
        angle_increment: std::f64::consts::TAU / beams as f64,
        ranges: &ranges,
        range_min: 0.05,
        range_max: 2.0 * radius + 1.0,
    })
    .unwrap()
}

fn sim_room() -> Vec<Scan> {
    use isoline_sim::lidar::{simulate, LidarParams, SceneKind};
    let mut p = LidarParams::new(SceneKind::Room);
    p.noise = Some(0.01);
    p.dropout = 0.02;
    p.frames = 2;
    simulate(&p)
        .unwrap()
        .iter()
        .map(|f| f.scan().unwrap())
        .collect()
}

/// Times `scan` cold, warm (after `previous`) and split-and-merge, in `group`.
fn frame_trio(c: &mut Criterion, name: &str, previous: &Scan, scan: &Scan) {
    let params = Params::default();
    let run = |s: &Scan, prev| reconstruct_with(&s.returns(), Some(s), &params, prev).unwrap();
    let first = run(previous, None);
    let sigma = run(scan, None).stats.range_noise.unwrap_or(0.01);
    let mut g = c.benchmark_group(name);
    g.sample_size(30);
    g.bench_function("cold", |b| b.iter(|| run(scan, None).stats.vertices));
    g.bench_function("warm", |b| {
        b.iter(|| run(scan, Some(&first)).stats.vertices)
    });
    g.bench_function("split_and_merge", |b| {
        b.iter(|| split_and_merge::lines(scan, sigma).len())
    });
    g.finish();
}

fn frames(c: &mut Criterion) {
    // One thread: wall time is CPU time. Errs only if a pool exists already.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    for (var, name) in [
        ("ISOLINE_BENCH_SICK", "sick_lms_180"),
        ("ISOLINE_BENCH_HOKUYO", "hokuyo_urg04lx_683"),
    ] {
        let pair = std::env::var(var).ok().and_then(|path| {
            let frames = read_input(Path::new(&path)).ok()?;
            let mid = frames.len() / 2;
            let prev = frames.get(mid.checked_sub(1)?)?.scan.clone()?;
            let scan = frames.get(mid)?.scan.clone()?;
            Some((prev, scan))
        });
        match pair {
            Some((prev, scan)) => frame_trio(c, name, &prev, &scan),
            None => {
                eprintln!("{name}: skipped ({var} unset or unreadable; see scripts/bench-scans.sh)")
            }
        }
    }
    let room = sim_room();
    assert_eq!(room[1].angles.len(), 1080);
    frame_trio(c, "sim_room_1080", &room[0], &room[1]);
}

fn scaling(c: &mut Criterion) {
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let params = Params::default();
    let run = |s: &Scan| reconstruct_with(&s.returns(), Some(s), &params, None).unwrap();
    let mut g = c.benchmark_group("scaling_returns");
    g.sample_size(10);
    for beams in [180, 360, 1080, 2000, 4000] {
        let scan = round_room(beams, 4.0, 1);
        g.bench_with_input(BenchmarkId::from_parameter(beams), &scan, |b, s| {
            b.iter(|| run(s).stats.vertices)
        });
    }
    g.finish();
    let mut g = c.benchmark_group("scaling_radius");
    g.sample_size(10);
    for radius in [2.0, 4.0, 8.0, 16.0, 32.0] {
        let scan = round_room(1080, radius, 2);
        g.bench_with_input(BenchmarkId::from_parameter(radius), &scan, |b, s| {
            b.iter(|| run(s).stats.vertices)
        });
    }
    g.finish();
}

/// The textbook line extractor the project compares against (the same steps as
/// `scripts/split_and_merge.py`): clusters by the adaptive breakpoint test, recursive
/// splitting at the return farthest from the chord, merging of neighbouring segments,
/// and a total-least-squares line per segment of three or more returns.
mod split_and_merge {
    use isoline_core::Scan;

    type P = [f64; 2];
    const LAMBDA: f64 = 10.0 * std::f64::consts::PI / 180.0;

    pub fn lines(scan: &Scan, sigma: f64) -> Vec<(P, P)> {
        let tol = (3.0 * sigma).max(0.02);
        let mut out = Vec::new();
        for cluster in clusters(scan, sigma) {
            let mut segs = Vec::new();
            split(&cluster, tol, &mut segs);
            let segs = merge(segs, tol);
            out.extend(segs.iter().filter(|s| s.len() >= 3).map(|s| fit(s)));
        }
        out
    }

    fn clusters(scan: &Scan, sigma: f64) -> Vec<Vec<P>> {
        let mut groups: Vec<Vec<P>> = Vec::new();
        let mut cur: Vec<P> = Vec::new();
        let mut last: Option<(f64, f64)> = None;
        for (i, &r) in scan.ranges.iter().enumerate() {
            if !r.is_finite() {
                continue;
            }
            let a = scan.angles[i];
            let p = [scan.origin[0] + r * a.cos(), scan.origin[1] + r * a.sin()];
            if let (Some((a0, r0)), Some(&p0)) = (last, cur.last()) {
                let dphi = (a - a0).abs();
                let reach = if dphi < LAMBDA {
                    r0.min(r) * dphi.sin() / (LAMBDA - dphi).sin()
                        + 3.0 * std::f64::consts::SQRT_2 * sigma
                } else {
                    -1.0
                };
                if (p[0] - p0[0]).hypot(p[1] - p0[1]) > reach {
                    groups.push(std::mem::take(&mut cur));
                }
            }
            cur.push(p);
            last = Some((a, r));
        }
        if !cur.is_empty() {
            groups.push(cur);
        }
        groups
    }

    fn chord(p: P, a: P, b: P) -> f64 {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let n = dx.hypot(dy);
        if n == 0.0 {
            return (p[0] - a[0]).hypot(p[1] - a[1]);
        }
        (dx * (a[1] - p[1]) - dy * (a[0] - p[0])).abs() / n
    }

    fn farthest(pts: &[P]) -> (usize, f64) {
        let (a, b) = (pts[0], pts[pts.len() - 1]);
        pts.iter()
            .enumerate()
            .map(|(k, &p)| (k, chord(p, a, b)))
            .fold((0, -1.0), |m, x| if x.1 > m.1 { x } else { m })
    }

    fn split(pts: &[P], tol: f64, out: &mut Vec<Vec<P>>) {
        if pts.len() < 3 {
            out.push(pts.to_vec());
            return;
        }
        let (k, d) = farthest(pts);
        if d > tol && k > 0 && k < pts.len() - 1 {
            split(&pts[..=k], tol, out);
            split(&pts[k..], tol, out);
        } else {
            out.push(pts.to_vec());
        }
    }

    fn merge(segs: Vec<Vec<P>>, tol: f64) -> Vec<Vec<P>> {
        let mut out: Vec<Vec<P>> = Vec::new();
        for s in segs {
            if let Some(last) = out.last_mut() {
                let mut joined = last.clone();
                joined.extend_from_slice(&s[1.min(s.len())..]);
                if farthest(&joined).1 <= tol {
                    *last = joined;
                    continue;
                }
            }
            out.push(s);
        }
        out
    }

    fn fit(pts: &[P]) -> (P, P) {
        let n = pts.len() as f64;
        let (mx, my) = pts
            .iter()
            .fold((0.0, 0.0), |(x, y), p| (x + p[0] / n, y + p[1] / n));
        let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
        for p in pts {
            let (dx, dy) = (p[0] - mx, p[1] - my);
            sxx += dx * dx;
            sxy += dx * dy;
            syy += dy * dy;
        }
        let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let (dx, dy) = (angle.cos(), angle.sin());
        let project = |p: P| {
            let t = (p[0] - mx) * dx + (p[1] - my) * dy;
            [mx + t * dx, my + t * dy]
        };
        (project(pts[0]), project(pts[pts.len() - 1]))
    }
}

criterion_group!(benches, frames, scaling);
criterion_main!(benches);

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::*;
use isoline_core::{reconstruct_scan, LaserScan, Params};

/// A room 6 m by 4 m with a pillar, and maybe a post of radius 0.2 m (a person).
struct Scene {
    walls: Vec<(Point, Point)>,
    post: Option<(Point, f64)>,
}

impl Scene {
    fn room() -> Scene {
        let c = [[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0]];
        let mut walls: Vec<(Point, Point)> = (0..4).map(|k| (c[k], c[(k + 1) % 4])).collect();
        // A square pillar 0.4 m wide.
        let p = [[3.8, 1.6], [4.2, 1.6], [4.2, 2.0], [3.8, 2.0]];
        walls.extend((0..4).map(|k| (p[k], p[(k + 1) % 4])));
        Scene { walls, post: None }
    }

    fn distance(&self, q: Point) -> f64 {
        self.walls
            .iter()
            .map(|&(a, b)| isoline_core::geom::point_segment_dist2(q, a, b).0.sqrt())
            .fold(f64::INFINITY, f64::min)
    }

    /// A 270-degree scan with 0.5-degree beams from `pose`, range noise `sigma`.
    fn scan(&self, pose: Pose, sigma: f64, rng: &mut rand_chacha::ChaCha8Rng) -> Scan {
        let noise = Normal::new(0.0, sigma).unwrap();
        let (start, step) = (-135f64.to_radians(), 0.5f64.to_radians());
        let o = [pose[0], pose[1]];
        let ranges: Vec<Option<f64>> = (0..541)
            .map(|k| {
                let a = pose[2] + start + k as f64 * step;
                let d = [a.cos(), a.sin()];
                let mut best = f64::INFINITY;
                for &(p, q) in &self.walls {
                    if let Some(t) = ray_segment(o, d, p, q) {
                        best = best.min(t);
                    }
                }
                if let Some((c, r)) = self.post {
                    let w = [c[0] - o[0], c[1] - o[1]];
                    let along = w[0] * d[0] + w[1] * d[1];
                    let off2 = w[0] * w[0] + w[1] * w[1] - along * along;
                    if off2 < r * r && along > 0.0 {
                        best = best.min(along - (r * r - off2).sqrt());
                    }
                }
                best.is_finite().then(|| best + noise.sample(rng))
            })
            .collect();
        laser(start, step, &ranges, 10.0)
    }
}

/// A scan at the origin with beams from `start` every `step`, ranges up to `range_max`.
fn laser(start: f64, step: f64, ranges: &[Option<f64>], range_max: f64) -> Scan {
    Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: start,
        angle_increment: step,
        ranges,
        range_min: 0.05,
        range_max,
    })
    .unwrap()
}

fn ray_segment(o: Point, d: Point, p: Point, q: Point) -> Option<f64> {
    let e = [q[0] - p[0], q[1] - p[1]];
    let den = d[0] * e[1] - d[1] * e[0];
    if den.abs() < 1e-12 {
        return None;
    }
    let w = [p[0] - o[0], p[1] - o[1]];
    let t = (w[0] * e[1] - w[1] * e[0]) / den;
    let s = (w[0] * d[1] - w[1] * d[0]) / den;
    (t > 0.0 && (0.0..=1.0).contains(&s)).then_some(t)
}

/// A drive round the room's free middle: `n` poses on an ellipse, facing along it.
fn drive(n: usize) -> Vec<Pose> {
    (0..n)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / n as f64;
            [
                3.0 - 2.0 * a.cos(),
                2.0 - 1.2 * a.sin(),
                a - std::f64::consts::FRAC_PI_2,
            ]
        })
        .collect()
}

fn build(scene: &Scene, poses: &[Pose], params: MapParams, seed: u64) -> Map {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut map = Map::new(params, Box::new(MemoryStore::default())).unwrap();
    for &pose in poses {
        let scan = scene.scan(pose, 0.01, &mut rng);
        let r = reconstruct_scan(&scan, &Params::default()).unwrap();
        map.insert(&scan, pose, &r.polylines, r.noise_estimate)
            .unwrap();
    }
    map
}

#[test]
fn a_room_driven_round_is_mapped_near_its_walls_and_nowhere_else() {
    let scene = Scene::room();
    let params = MapParams::default();
    let mut map = build(&scene, &drive(24), params, 1);
    let (curves, scores) = map.finish().unwrap();
    // Each scan's curves lie within 3 sigma + 2 hmin of the walls (the single-frame
    // bound); their average lies closer, and the lattice adds at most half a cell's
    // interpolation error at corners.
    let bound = 3.0 * 0.01 + 0.5 * params.cell;
    let worst = curves
        .iter()
        .flat_map(|c| c.points.iter())
        .map(|&p| scene.distance(p))
        .fold(0.0, f64::max);
    assert!(worst <= bound, "worst {worst} > {bound}");
    // Every wall is there: the room's 20 m and the pillar's 1.6 m, less what the
    // pillar hides and corners' rounding.
    assert!(scores.length > 0.9 * 21.6, "{scores:?}");
    assert!(scores.static_within >= 0.95, "{scores:?}");
    assert!(scores.seen_through <= 0.01, "{scores:?}");
    // A compact map: the room's walls one closed loop; the rest is the pillar, whose
    // sides the scans see one or two at a time (a scan's curve ends at the pillar's
    // silhouette, and an end carries no signed distance), so its corners may part.
    let lengths: Vec<(f64, bool)> = curves.iter().map(|c| (c.length(), c.closed)).collect();
    let rooms: Vec<&Polyline> = curves
        .iter()
        .filter(|c| c.closed && (c.length() - 20.0).abs() < 0.5)
        .collect();
    assert_eq!(rooms.len(), 1, "{lengths:?}");
    assert!(curves.len() <= 5, "{lengths:?}");
    for c in curves.iter().filter(|c| !(c.closed && c.length() > 19.0)) {
        assert!(
            c.points
                .iter()
                .all(|p| (p[0] - 4.0).abs() < 0.3 && (p[1] - 1.8).abs() < 0.3),
            "{c:?}"
        );
    }
    assert!(scores.union_length > 10.0 * scores.length, "{scores:?}");
    // The free side is on the left: a point a few centimetres to a curve's left is
    // farther from the walls' inside than the curve (inside the room, off the pillar).
    for c in &curves {
        for w in c.points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let l = isoline_core::geom::dist(a, b);
            if l < 0.05 {
                continue;
            }
            let m = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
            let left = [
                m[0] - 0.05 * (b[1] - a[1]) / l,
                m[1] + 0.05 * (b[0] - a[0]) / l,
            ];
            let inside_room = left[0] > 0.0 && left[0] < 6.0 && left[1] > 0.0 && left[1] < 4.0;
            let in_pillar = left[0] > 3.8 && left[0] < 4.2 && left[1] > 1.6 && left[1] < 2.0;
            assert!(inside_room && !in_pillar, "{left:?} left of {a:?}-{b:?}");
        }
    }
}

#[test]
fn a_person_who_walked_away_leaves_the_map() {
    // A person stands in the room for the first third of the drive, then is gone: the
    // beams of the later scans sweep where they stood.
    let poses = drive(24);
    let mut scene = Scene::room();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let mut map = Map::new(MapParams::default(), Box::new(MemoryStore::default())).unwrap();
    let person = [2.0, 2.0];
    for (k, &pose) in poses.iter().enumerate() {
        scene.post = (k < 8).then_some((person, 0.2));
        let scan = scene.scan(pose, 0.01, &mut rng);
        let r = reconstruct_scan(&scan, &Params::default()).unwrap();
        map.insert(&scan, pose, &r.polylines, r.noise_estimate)
            .unwrap();
        if k == 7 {
            // While they stand there, they are in the map.
            let near = map
                .curves()
                .unwrap()
                .iter()
                .flat_map(|c| c.points.clone())
                .filter(|&p| isoline_core::geom::dist(p, person) < 0.3)
                .count();
            assert!(near > 0, "the person was never mapped");
        }
    }
    let (curves, _) = map.finish().unwrap();
    let near: Vec<Point> = curves
        .iter()
        .flat_map(|c| c.points.iter().copied())
        .filter(|&p| isoline_core::geom::dist(p, person) < 0.5)
        .collect();
    assert!(near.is_empty(), "still mapped: {near:?}");
}

#[test]
fn tiles_that_leave_memory_come_back_and_the_map_stays_the_same() {
    let scene = Scene::room();
    let poses = drive(16);
    // Tiles of 0.24 m and beams of 2 m: one scan touches at most 19 x 19 tiles, the
    // room's walls lie in about 440.
    // With the alignment too: the tiles under a scan's returns come back before it is
    // laid on the map, so what it is laid on does not depend on the memory bound.
    for align in [false, true] {
        let roomy = MapParams {
            tile: 8,
            max_range: 2.0,
            max_tiles: 100_000,
            align,
            ..MapParams::default()
        };
        let tight = MapParams {
            max_tiles: roomy.tiles_per_scan(),
            ..roomy
        };
        let mut a = build(&scene, &poses, roomy, 3);
        let mut b = build(&scene, &poses, tight, 3);
        assert!(b.stats().spills > 0, "{:?}", b.stats());
        assert!(b.stats().tiles_resident <= tight.max_tiles);
        let (ca, sa) = a.finish().unwrap();
        let (cb, sb) = b.finish().unwrap();
        assert!(b.stats().tiles_resident <= tight.max_tiles);
        assert_eq!(ca, cb, "align {align}");
        assert_eq!(sa, sb, "align {align}");
    }
}

#[test]
fn parameters_that_cannot_hold_a_scan_are_refused() {
    let p = MapParams {
        max_tiles: 3,
        ..MapParams::default()
    };
    let e = Map::new(p, Box::new(MemoryStore::default())).unwrap_err();
    assert!(e.to_string().contains("map.max_tiles"), "{e}");
    for bad in [
        MapParams {
            cell: 0.0,
            ..MapParams::default()
        },
        MapParams {
            min_scans: 0,
            ..MapParams::default()
        },
        MapParams {
            hit_tolerance: f64::NAN,
            ..MapParams::default()
        },
        MapParams {
            heading_noise: -0.01,
            ..MapParams::default()
        },
        MapParams {
            heading_noise: f64::INFINITY,
            ..MapParams::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}

/// A wall along `y = 2`, seen twice from 1 m (curves on it) and twice from 12 m by a
/// scan whose heading error put its curve 6 cm off (what 0.29 degrees does at that
/// range). With the default heading noise (0.5 degrees) and 1 cm of range noise the
/// near scans weigh `1 / (1 + 0.87^2)` and the far ones `1 / (1 + 10.4^2)`, so the
/// wall is the weighted average: 0.95 mm off the near scans' line, where the plain
/// average (heading noise 0) puts it at 3 cm. The lattice interpolates the average
/// linearly between samples whose weights differ by their 3 cm in range: to 0.2 mm.
#[test]
fn a_wall_lies_where_the_scans_that_saw_it_from_near_put_it() {
    let wall_scan = |sensor: Point, wall: f64| -> (Scan, Vec<Polyline>) {
        let (start, step) = (45f64.to_radians(), 0.5f64.to_radians());
        let ranges: Vec<Option<f64>> = (0..181)
            .map(|k| {
                let a = start + k as f64 * step;
                Some((wall - sensor[1]) / a.sin())
            })
            .collect();
        let scan = laser(start, step, &ranges, 30.0);
        // The free side (towards the sensor, below) on the curve's left: it runs to -x.
        let dy = wall - sensor[1];
        let curve = Polyline {
            closed: false,
            points: vec![[dy, dy], [0.0, dy], [-dy, dy]],
        };
        (scan, vec![curve])
    };
    let wall_at = |heading_noise: f64| -> f64 {
        let params = MapParams {
            heading_noise,
            ..MapParams::default()
        };
        let mut map = Map::new(params, Box::new(MemoryStore::default())).unwrap();
        for (sensor, wall) in [([0.0, 1.0], 2.0), ([0.0, -10.0], 2.06)] {
            let (scan, curves) = wall_scan(sensor, wall);
            for _ in 0..2 {
                map.insert(&scan, [sensor[0], sensor[1], 0.0], &curves, 0.01)
                    .unwrap();
            }
        }
        let (curves, _) = map.finish().unwrap();
        // Where the map's curve crosses x = 0 (it is simplified: no vertex need lie there).
        curves
            .iter()
            .flat_map(|c| c.points.windows(2))
            .find(|w| (w[0][0] >= 0.0) != (w[1][0] >= 0.0))
            .map(|w| {
                let t = w[0][0] / (w[0][0] - w[1][0]);
                w[0][1] + t * (w[1][1] - w[0][1])
            })
            .unwrap_or_else(|| panic!("no wall across x = 0: {curves:?}"))
    };
    let (near, far) = (
        1.0 / (1.0 + 0.87f64.powi(2)),
        1.0 / (1.0 + 10.44f64.powi(2)),
    );
    let weighted = 2.0 + 0.06 * far / (near + far);
    let y = wall_at(0.5f64.to_radians());
    assert!((y - weighted).abs() < 2e-4, "{y} against {weighted}");
    let y = wall_at(0.0);
    assert!((y - 2.03).abs() < 2e-4, "{y} against 2.03");
}

/// A curve is cut where it leaves the disc: an open line from the centre out to 30
/// ends on the circle of 20; a closed circle of radius 10 about (15, 0) keeps the arc
/// inside, whose two ends lie on the circle, as one open piece.
#[test]
fn curves_are_cut_to_the_beams_reach() {
    let line = Polyline {
        closed: false,
        points: (0..=30).map(|k| [k as f64, 0.0]).collect(),
    };
    let cut = within(&[line], [0.0, 0.0], 20.0);
    assert_eq!(cut.len(), 1);
    assert_eq!(cut[0].points.first(), Some(&[0.0, 0.0]));
    assert!(isoline_core::geom::dist(*cut[0].points.last().unwrap(), [20.0, 0.0]) < 1e-12);
    let ring = Polyline {
        closed: true,
        points: (0..64)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 64.0;
                [15.0 + 10.0 * a.cos(), 10.0 * a.sin()]
            })
            .collect(),
    };
    let cut = within(&[ring], [0.0, 0.0], 20.0);
    assert_eq!(cut.len(), 1, "{cut:?}");
    let r = |p: &Point| isoline_core::geom::dist(*p, [0.0, 0.0]);
    assert!(cut[0].points.iter().all(|p| r(p) <= 20.0 + 1e-9));
    for end in [cut[0].points[0], *cut[0].points.last().unwrap()] {
        assert!((r(&end) - 20.0).abs() < 1e-9, "{end:?}");
    }
}

/// A scanner that reports "no return" as 50 m draws an arc there; the map counts beams
/// up to `max_range` (20 m), so the arc is no wall of the map and opens no tile beyond
/// the ones a scan may touch.
#[test]
fn curves_past_the_beams_reach_stay_out_of_the_map() {
    let (start, step) = (-90f64.to_radians(), 1f64.to_radians());
    let ranges: Vec<Option<f64>> = (0..181).map(|_| Some(50.0)).collect();
    let scan = laser(start, step, &ranges, 80.0);
    let arc = Polyline {
        closed: false,
        points: (0..181)
            .rev()
            .map(|k| {
                let a = start + k as f64 * step;
                [50.0 * a.cos(), 50.0 * a.sin()]
            })
            .collect(),
    };
    let params = MapParams::default();
    let mut map = Map::new(params, Box::new(MemoryStore::default())).unwrap();
    for _ in 0..3 {
        map.insert(&scan, [0.0, 0.0, 0.0], std::slice::from_ref(&arc), 0.01)
            .unwrap();
    }
    assert!(map.stats().tiles_resident <= params.tiles_per_scan());
    let (curves, _) = map.finish().unwrap();
    assert!(curves.is_empty(), "{curves:?}");
}

#[test]
fn a_pose_beyond_the_lattice_is_refused_and_the_map_goes_on() {
    let scene = Scene::room();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let params = MapParams::default();
    let mut map = Map::new(params, Box::new(MemoryStore::default())).unwrap();
    let pose = [3.0, 2.0, 0.0];
    let scan = scene.scan(pose, 0.01, &mut rng);
    let curves = reconstruct_scan(&scan, &Params::default())
        .unwrap()
        .polylines;
    // The scan's own frame is the world's here: place it by a pose that moves it far.
    let local = laser(
        -135f64.to_radians(),
        0.5f64.to_radians(),
        &[Some(2.0); 541],
        10.0,
    );
    let limit = params.max_coordinate();
    // Beyond the limit (2^31 cells), up to the point where the index would saturate
    // and the ray walk would never end: refused, counted, nothing touched.
    for far in [limit * 1.01, 1e12, 2.8e17, 1e300] {
        let e = map.insert(&local, [far, 0.0, 0.0], &[], 0.01).unwrap_err();
        assert!(matches!(e, Error::PoseOutOfReach { .. }), "{e}");
        assert_eq!(map.stats().tiles_resident, 0);
    }
    assert_eq!(map.stats().scans_refused, 4);
    assert_eq!(map.stats().scans, 0);
    // Within it, far from the origin (1,000 km), the map is as good as at home.
    let worst = |map: &Map, at: [f64; 2]| {
        let walls = map.curves().unwrap();
        assert!(!walls.is_empty());
        walls
            .iter()
            .flat_map(|w| &w.points)
            .map(|q| scene.distance([q[0] - at[0], q[1] - at[1]]))
            .fold(0.0, f64::max)
    };
    let mut home = Map::new(params, Box::new(MemoryStore::default())).unwrap();
    let away = [1e6, -1e6];
    for _ in 0..3 {
        home.insert(&scan, pose, &curves, 0.01).unwrap();
        let p = [pose[0] + away[0], pose[1] + away[1], 0.0];
        map.insert(&scan, p, &curves, 0.01).unwrap();
    }
    let (w_home, w_away) = (worst(&home, [0.0, 0.0]), worst(&map, away));
    // The lattice lies differently under the walls there: within a cell of home's.
    assert!(w_away <= w_home + params.cell, "{w_away} vs {w_home}");
}

#[test]
fn tolerances_that_would_break_the_memory_bound_are_refused_or_capped() {
    let base = MapParams {
        tile: 16,
        max_range: 3.0,
        ..MapParams::default()
    };
    for tol in [50.0, 1000.0] {
        let p = MapParams {
            hit_tolerance: tol,
            ..base
        };
        let e = p.validate().unwrap_err().join("; ");
        assert!(e.contains("map.hit_tolerance"), "{e}");
    }
    // A scan's range noise is the data's: one of 50 m or 1000 m (a wrong estimate, a
    // wrong setting) is taken at most as wide as the bound counts, and the tiles in
    // memory stay within max_tiles.
    let tight = MapParams {
        max_tiles: base.tiles_per_scan(),
        ..base
    };
    let scene = Scene::room();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let mut map = Map::new(tight, Box::new(MemoryStore::default())).unwrap();
    for (k, pose) in drive(8).into_iter().enumerate() {
        let scan = scene.scan(pose, 0.01, &mut rng);
        let curves = reconstruct_scan(&scan, &Params::default())
            .unwrap()
            .polylines;
        let noise = if k % 2 == 0 { 50.0 } else { 1000.0 };
        map.insert(&scan, pose, &curves, noise).unwrap();
        assert!(
            map.stats().tiles_resident <= tight.max_tiles,
            "{:?}",
            map.stats()
        );
    }
}

#[test]
fn the_store_holds_at_most_max_stored_tiles() {
    let scene = Scene::room();
    let params = MapParams {
        tile: 16,
        max_range: 3.0,
        max_stored_tiles: 40,
        ..MapParams::default()
    };
    let params = MapParams {
        max_tiles: params.tiles_per_scan(),
        ..params
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut map = Map::new(params, Box::new(MemoryStore::default())).unwrap();
    // Poses that jump 100 m every other scan: each pair needs tiles of its own.
    for k in 0..60 {
        let pose = [3.0, 2.0, 0.0];
        let scan = scene.scan(pose, 0.01, &mut rng);
        let curves = reconstruct_scan(&scan, &Params::default())
            .unwrap()
            .polylines;
        map.insert(&scan, [100.0 * (k / 2) as f64, 0.0, 0.0], &curves, 0.01)
            .unwrap();
        let s = map.stats();
        assert!(
            s.tiles_stored <= 40 && s.tiles_resident <= params.max_tiles,
            "{s:?}"
        );
    }
    let s = map.stats();
    assert!(s.tiles_dropped > 0, "{s:?}");
    // What is left is the most recently seen: the last scan's walls are in the map.
    let (walls, _) = map.finish().unwrap();
    assert!(walls.iter().flat_map(|w| &w.points).any(|q| q[0] > 2900.0));
}

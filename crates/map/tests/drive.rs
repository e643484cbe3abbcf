//! Registration on simulated drives with known poses: the estimate against the truth,
//! by the trajectory scores a user would compute.

use isoline_core::{Pose, Scan};
use isoline_map::trajectory::{absolute, relative};
use isoline_map::{between, compose, RegisterParams, Registrar};
use isoline_sim::lidar::{simulate, LidarParams, ScanFrame, SceneKind, SensorModel};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn scan(f: &ScanFrame) -> Scan {
    f.scan().unwrap()
}

/// Two laps of the corridor scene's 38 m stadium, a SICK LMS1xx scan every 25 cm.
fn drive() -> Vec<ScanFrame> {
    let mut p = LidarParams::new(SceneKind::Corridor);
    p.sensor = SensorModel::named("sick-lms1xx").unwrap();
    p.noise = Some(0.01);
    p.frames = 300;
    p.motion = 0.25;
    simulate(&p).unwrap()
}

/// Dead reckoning over the true steps with wheel errors: 2% too long, a heading bias
/// of 1 degree a metre, and 2% (translation) and 0.3 degrees a metre (heading) of
/// random error, seeded.
fn odometry(truth: &[Pose], seed: u64) -> Vec<Pose> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut out = vec![truth[0]];
    for w in truth.windows(2) {
        let s = between(w[0], w[1]);
        let d = s[0].hypot(s[1]);
        let noisy = [
            s[0] * 1.02 + 0.02 * d * unit.sample(&mut rng),
            s[1] * 1.02 + 0.02 * d * unit.sample(&mut rng),
            s[2] + 1f64.to_radians() * d + 0.3f64.to_radians() * d * unit.sample(&mut rng),
        ];
        out.push(compose(*out.last().unwrap(), noisy));
    }
    out
}

fn register(frames: &[ScanFrame], input: &[Pose], params: RegisterParams) -> (Vec<Pose>, usize) {
    let mut reg = Registrar::new(params).unwrap();
    for (f, &p) in frames.iter().zip(input) {
        reg.push(&scan(f), Some(p));
    }
    let poses = reg.finish();
    (poses, reg.loops())
}

#[test]
fn registration_removes_the_odometrys_drift_and_loops_keep_it_removed() {
    let frames = drive();
    let truth: Vec<Pose> = frames.iter().map(|f| f.pose).collect();
    let odom = odometry(&truth, 7);
    let dead = absolute(&odom, &truth);
    let (open, _) = register(
        &frames,
        &odom,
        RegisterParams {
            loops: false,
            ..Default::default()
        },
    );
    let (closed, loops) = register(&frames, &odom, RegisterParams::default());
    let (open_e, closed_e) = (absolute(&open, &truth), absolute(&closed, &truth));
    eprintln!(
        "ATE: odometry {:.3} m, registered {:.3} m, loops closed ({loops}) {:.3} m",
        dead.ate, open_e.ate, closed_e.ate
    );
    // A degree a metre over 76 m turns the odometry through 76 degrees: metres off.
    assert!(dead.ate > 1.0, "{dead:?}");
    // The walls fix the heading scan to scan; what is left drifts along the corridor.
    assert!(open_e.ate < 0.2 * dead.ate, "{open_e:?} against {dead:?}");
    // The second lap meets the first and closes loops; where scan matching alone is
    // already within millimetres they cannot improve it, and must not spoil it beyond
    // the loop edges' own floor (1.5 cm, docs/method.md).
    assert!(loops > 0);
    assert!(closed_e.ate < 0.03, "{closed_e:?} against {open_e:?}");
    // Over a metre of path the registered motion is off by a few centimetres at most
    // (the scans' 1 cm noise over a few hundred returns, and the corridor's axis where
    // the odometry decides).
    let r1 = relative(&closed, &truth, 1.0);
    assert!(
        r1.translation < 0.05 && r1.heading < 0.5f64.to_radians(),
        "{r1:?}"
    );
}

#[test]
fn with_exact_poses_registration_stays_on_them() {
    let frames = drive();
    let truth: Vec<Pose> = frames.iter().map(|f| f.pose).collect();
    let (est, _) = register(&frames[..120], &truth[..120], RegisterParams::default());
    let e = absolute(&est, &truth[..120]);
    let r1 = relative(&est, &truth[..120], 1.0);
    eprintln!("{e:?} {r1:?}");
    // Good poses in, the same poses out within the scan matching's error.
    assert!(e.ate < 0.05, "{e:?}");
    assert!(r1.heading < 0.3f64.to_radians(), "{r1:?}");
}

/// A Hokuyo URG-04LX's sweep through the clutter scene, a scan every 5 cm at 10 Hz,
/// each beam cast from where the sensor is when it is taken (67 ms over the 240
/// degrees): its frames corrected by the odometry's motion (`Scan::deskewed`) are
/// registered as well as a scanner taking its beams at once, where read as taken at
/// once they bend with every turn.
#[test]
fn a_sweeping_scanners_frames_are_registered_once_corrected_for_the_sweep() {
    let mut p = LidarParams::new(SceneKind::Clutter);
    p.sensor = SensorModel::named("hokuyo-urg04lx").unwrap();
    p.frames = 400;
    p.motion = 0.05;
    p.sweep = true;
    let frames = simulate(&p).unwrap();
    let truth: Vec<Pose> = frames.iter().map(|f| f.pose).collect();
    let odom = odometry(&truth, 3);
    let mut corrected = Registrar::new(RegisterParams::default()).unwrap();
    let mut raw = Registrar::new(RegisterParams::default()).unwrap();
    for (k, f) in frames.iter().enumerate() {
        let scan = scan(f);
        let fixed = match k.checked_sub(1) {
            Some(j) => isoline_core::velocity(odom[j], odom[k], f.t - frames[j].t)
                .map_or_else(|| scan.clone(), |v| scan.deskewed(&f.sweep(), v)),
            None => scan.clone(),
        };
        corrected.push(&fixed, Some(odom[k]));
        raw.push(&scan, Some(odom[k]));
    }
    let (corrected, raw) = (corrected.finish(), raw.finish());
    // The same drive by a scanner taking its beams at once.
    p.sweep = false;
    let still = simulate(&p).unwrap();
    let (at_once, _) = register(&still, &odom, RegisterParams::default());
    let (c1, r1, s1) = (
        relative(&corrected, &truth, 1.0),
        relative(&raw, &truth, 1.0),
        relative(&at_once, &truth, 1.0),
    );
    eprintln!(
        "over 1 m: corrected {:.4} m {:.3} deg, raw {:.4} m {:.3} deg, at once {:.4} m {:.3} \
         deg; ATE {:.4} / {:.4} / {:.4} m",
        c1.translation,
        c1.heading.to_degrees(),
        r1.translation,
        r1.heading.to_degrees(),
        s1.translation,
        s1.heading.to_degrees(),
        absolute(&corrected, &truth).ate,
        absolute(&raw, &truth).ate,
        absolute(&at_once, &truth).ate,
    );
    // Read as taken at once, each turn bends the sweep and the fit takes part of the
    // bend for a turn of the whole scan.
    assert!(c1.heading < 0.5 * r1.heading, "{c1:?} against {r1:?}");
    // Corrected, what is left is the correction's own error: the odometry's motion
    // over the last frame taken for the sweep's (its 2% and 0.3 degrees a metre of
    // noise, and the change of the turn rate within a frame), well under the bend.
    assert!(
        c1.heading < 1.5 * s1.heading && c1.translation < 1.5 * s1.translation,
        "{c1:?} against {s1:?}"
    );
}

/// An RPLIDAR A1's drive through the clutter scene without any pose (a handheld or a
/// hobby robot's scanner): its 360-degree sweep takes the whole 100 ms between frames,
/// and the motion to correct it by is only what registration itself gives
/// (`Registrar::push_swept`).
#[test]
fn a_sweeping_scanner_without_poses_is_corrected_by_its_own_registration() {
    let mut p = LidarParams::new(SceneKind::Clutter);
    p.sensor = SensorModel::named("rplidar-a1").unwrap();
    p.frames = 300;
    p.motion = 0.05;
    p.seed = 2;
    p.sweep = true;
    let frames = simulate(&p).unwrap();
    let truth: Vec<Pose> = frames.iter().map(|f| f.pose).collect();
    let mut swept = Registrar::new(RegisterParams::default()).unwrap();
    let mut raw = Registrar::new(RegisterParams::default()).unwrap();
    for f in &frames {
        swept.push_swept(&scan(f), &f.sweep(), f.t, None);
        raw.push(&scan(f), None);
    }
    let (swept, raw) = (swept.finish(), raw.finish());
    p.sweep = false;
    let still = simulate(&p).unwrap();
    let mut at_once = Registrar::new(RegisterParams::default()).unwrap();
    for f in &still {
        at_once.push(&scan(f), None);
    }
    let at_once = at_once.finish();
    let (w1, r1, s1) = (
        relative(&swept, &truth, 1.0),
        relative(&raw, &truth, 1.0),
        relative(&at_once, &truth, 1.0),
    );
    eprintln!(
        "over 1 m: corrected {:.4} m {:.3} deg, raw {:.4} m {:.3} deg, at once {:.4} m {:.3} deg",
        w1.translation,
        w1.heading.to_degrees(),
        r1.translation,
        r1.heading.to_degrees(),
        s1.translation,
        s1.heading.to_degrees(),
    );
    // Read as taken at once, a sweep as long as the frame bends by a whole frame's turn.
    assert!(w1.heading < 0.5 * r1.heading, "{w1:?} against {r1:?}");
    // Corrected by its own estimates, what is added to the error of a scanner taking
    // its beams at once is the estimated motion's over one frame: two estimates'
    // difference (sqrt 2 of one's error), bending a sweep as long as the frame.
    let bound = 1.0 + std::f64::consts::SQRT_2;
    assert!(
        w1.heading < bound * s1.heading && w1.translation < bound * s1.translation,
        "{w1:?} against {s1:?}"
    );
}

//! What the benchmarks share: their inputs. The benchmarks themselves are in
//! `benches/benches/` (`cargo bench -p isoline-bench --bench NAME`); this crate is not
//! built by the test suite, so that criterion is not either.

#![forbid(unsafe_code)]

use isoline_sim::{generate, Shape, SynthParams};

/// The simulator's circle of radius 0.4 with `points` samples and range noise `noise`
/// (seed 1).
pub fn circle(points: usize, noise: f64) -> Vec<[f64; 2]> {
    let mut p = SynthParams::new(Shape::Circle);
    p.points = points;
    p.noise = noise;
    generate(&p)
        .expect("the circle is generated")
        .remove(0)
        .points
}

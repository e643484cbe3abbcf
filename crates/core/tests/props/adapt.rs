//! Property tests: adaptation keeps the mesh valid for any point set, degenerate ones
//! included.

use isoline_core::stages::adapt_to_points;
use isoline_core::MeshParams;
use proptest::prelude::*;

fn check(points: &[[f64; 2]]) -> Result<(), TestCaseError> {
    // Coarse sizes keep each case fast; validity does not depend on the scale.
    let m = adapt_to_points(
        points,
        &MeshParams::default().with_hmin(0.02).with_hmax(0.2),
    )
    .map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(m.mesh.sanity_check(), Ok(()));
    prop_assert!(m.stats.min_quality > 0.0);
    // The mesh covers the padded domain: triangle areas sum to the box area.
    let area: f64 = (0..m.mesh.num_triangles())
        .map(|t| {
            let [a, b, c] = m.mesh.tri_coords(t);
            isoline_core::geom::area(a, b, c)
        })
        .sum();
    let s = m.domain.size();
    prop_assert!((area - s[0] * s[1]).abs() <= 1e-9 * s[0] * s[1]);
    Ok(())
}

fn coord() -> impl Strategy<Value = f64> {
    -1.0..1.0f64
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn random_clouds(points in prop::collection::vec([coord(), coord()], 1..300)) {
        check(&points)?;
    }

    #[test]
    fn collinear(a in coord(), b in coord(), dx in coord(), dy in coord(), n in 1usize..200) {
        let pts: Vec<[f64; 2]> = (0..n).map(|i| {
            let t = i as f64 / n as f64;
            [a + t * dx, b + t * dy]
        }).collect();
        check(&pts)?;
    }

    #[test]
    fn all_equal_and_single(x in coord(), y in coord(), n in 1usize..50) {
        check(&vec![[x, y]; n])?;
    }

    #[test]
    fn clustered_with_duplicates(c in prop::collection::vec([coord(), coord()], 1..5), n in 1usize..200) {
        let pts: Vec<[f64; 2]> = (0..n).map(|i| {
            let k = c[i % c.len()];
            [k[0] + 1e-9 * (i % 3) as f64, k[1]]
        }).collect();
        check(&pts)?;
    }
}

use super::*;
use crate::geom::BBox;
use crate::mesh::VertexTag;

fn square() -> BBox {
    BBox {
        min: [0.0, 0.0],
        max: [1.0, 1.0],
    }
}

struct Recovered {
    grad: Vec<Point>,
    hess_l2: Vec<Sym2>,
    hess_ls: Vec<Sym2>,
}

fn recover(mesh: &Mesh, f: impl Fn(Point) -> f64) -> Recovered {
    let sp = P1Space::new(mesh);
    let u: Vec<f64> = mesh.coords.iter().map(|&p| f(p)).collect();
    let (nv, nt) = (mesh.num_vertices(), mesh.num_triangles());
    let mut elem = vec![[0.0; 2]; nt];
    let mut grad = vec![[0.0; 2]; nv];
    sp.recover_gradient(mesh, &u, &mut elem, &mut grad);
    let mut hess_l2 = vec![Sym2::default(); nv];
    sp.recover_hessian_l2(mesh, &grad, &mut HessianScratch::default(), &mut hess_l2);
    let mut hess_ls = vec![Sym2::default(); nv];
    sp.recover_hessian_ls(mesh, &u, &grad, Some(&hess_l2), &mut hess_ls);
    Recovered {
        grad,
        hess_l2,
        hess_ls,
    }
}

fn hess_err(h: &Sym2, e: &Sym2) -> f64 {
    (h.xx - e.xx)
        .abs()
        .max((h.xy - e.xy).abs())
        .max((h.yy - e.yy).abs())
}

#[test]
fn linear_fields_are_recovered_exactly_on_an_unstructured_mesh() {
    let mesh = Mesh::of_box(&square(), 0.07);
    let r = recover(&mesh, |p| 2.0 * p[0] - 3.0 * p[1] + 1.0);
    for v in 0..mesh.num_vertices() {
        assert!((r.grad[v][0] - 2.0).abs() < 1e-11 && (r.grad[v][1] + 3.0).abs() < 1e-11);
        assert!(hess_err(&r.hess_l2[v], &Sym2::default()) < 1e-9);
        assert!(hess_err(&r.hess_ls[v], &Sym2::default()) < 1e-9);
    }
}

#[test]
fn quadratics_are_exact_at_interior_vertices_of_a_structured_mesh() {
    // Point-symmetric balls make the area-weighted gradient exact for quadratics, and
    // then the eq. 10 fit is exact too.
    let mesh = Mesh::structured(&square(), 10);
    let exact = Sym2 {
        xx: 2.0,
        xy: 3.0,
        yy: -4.0,
    };
    let r = recover(&mesh, |p| {
        p[0] * p[0] + 3.0 * p[0] * p[1] - 2.0 * p[1] * p[1]
    });
    for v in 0..mesh.num_vertices() {
        if mesh.tag[v] != VertexTag::Interior {
            continue;
        }
        let [x, y] = mesh.coords[v];
        let g = [2.0 * x + 3.0 * y, 3.0 * x - 4.0 * y];
        assert!((r.grad[v][0] - g[0]).abs() < 1e-11 && (r.grad[v][1] - g[1]).abs() < 1e-11);
        assert!(hess_err(&r.hess_ls[v], &exact) < 1e-8, "{:?}", r.hess_ls[v]);
    }
}

/// Observed orders of convergence under refinement for a smooth non-polynomial field on
/// structured meshes, measured at vertices at least 0.2 from the boundary (the one-sided
/// boundary balls are first order, by design of the L2 projection).
fn observed_orders() -> (f64, f64, f64) {
    let f = |p: Point| (2.0 * p[0]).sin() * (3.0 * p[1]).cos();
    let g = |p: Point| {
        [
            2.0 * (2.0 * p[0]).cos() * (3.0 * p[1]).cos(),
            -3.0 * (2.0 * p[0]).sin() * (3.0 * p[1]).sin(),
        ]
    };
    let h = |p: Point| Sym2 {
        xx: -4.0 * f(p),
        xy: -6.0 * (2.0 * p[0]).cos() * (3.0 * p[1]).sin(),
        yy: -9.0 * f(p),
    };
    let mut errs = Vec::new();
    for n in [10, 20, 40, 80] {
        let mesh = Mesh::structured(&square(), n);
        let r = recover(&mesh, f);
        let (mut eg, mut el2, mut els) = (0f64, 0f64, 0f64);
        for (v, &p) in mesh.coords.iter().enumerate() {
            if p.iter().any(|&c| !(0.2..=0.8).contains(&c)) {
                continue;
            }
            let ge = g(p);
            eg = eg.max(
                (r.grad[v][0] - ge[0])
                    .abs()
                    .max((r.grad[v][1] - ge[1]).abs()),
            );
            el2 = el2.max(hess_err(&r.hess_l2[v], &h(p)));
            els = els.max(hess_err(&r.hess_ls[v], &h(p)));
        }
        errs.push((eg, el2, els));
    }
    let order = |a: f64, b: f64| (a / b).log2();
    let k = errs.len() - 1;
    (
        order(errs[k - 1].0, errs[k].0),
        order(errs[k - 1].1, errs[k].1),
        order(errs[k - 1].2, errs[k].2),
    )
}

#[test]
fn recovery_converges_at_the_expected_rates() {
    let (og, ol2, ols) = observed_orders();
    // Theory on point-symmetric stencils: the recovered gradient superconverges at
    // O(h^2); both Hessians, built from it, are O(h^2) there too (O(h) on general meshes).
    assert!(og > 1.8, "gradient order {og}");
    assert!(ol2 > 1.8, "L2 Hessian order {ol2}");
    assert!(ols > 1.8, "least-squares Hessian order {ols}");
}

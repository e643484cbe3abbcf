//! A point cloud's curves drawn through its samples by a graph: the point-cloud curve
//! stage where the level set has no curve to follow (a noise band wider than most of
//! the noise measurement's windows, where [`crate::reconstruct`] once gave up).
//!
//! Its contract, met by construction rather than by a cut afterwards:
//! - every vertex is a sample moved onto the curve its own window sees, by at most
//!   three of the window's residuals, or the corner where two ends' directions meet
//!   within two windows of each and within its window of a sample; a sample whose
//!   window never sees a curve is in none;
//! - every edge of the tree joins two vertices within both their windows; a join of
//!   two ends spans at most two windows (a gap wider stays open);
//! - no two edges cross (the tree's edges are Delaunay edges, and every join is added
//!   only where it crosses none);
//! - no vertex is a star: a Euclidean minimum spanning tree's vertex has at most six
//!   edges, a join goes to a vertex of at most two, and two forks merge only into one
//!   of at most six.
//!
//! The steps, each with its reason:
//! 0. *Density.* Where a typical sample's ten nearest lie within half the noise, the
//!    graph runs on a uniform subsample in which they lie that far ([`thinned`]): more
//!    samples sharpen no fit whose residual the noise sets, and they cost every
//!    window's fit.
//!
//!    *Area.* Where fewer than [`AREA_SHARE`] of the samples' windows see a curve
//!    (below), the samples fill an area and nothing is drawn: in scattered points
//!    windows pass by chance, at the edges of the area they fill.
//! 1. *Windows.* Each sample's window grows from the radius of its ten nearest samples
//!    by a quarter at a time until the fit of its own sheet within it holds ten samples
//!    and spans four times its residual (the noise measurement's rule,
//!    [`crate::mesh::metric`]): the smallest window in which the samples look like a
//!    curve rather than a blob. Up to [`largest_window`], or [`SPARSER`] times a typical
//!    sample's ten-sample radius where the sampling is sparser ([`window_cap`]). A sample
//!    whose own ten lie farther is tried once, at their radius, and qualifies only if
//!    they lie within the accuracy bound of their fit: a sparse stretch of a curve's ten
//!    do, ten scattered points' do not. A sample whose window never qualifies lies in an
//!    area, not on a curve.
//! 2. *Onto the curve.* The sample moves to the fitted parabola's foot (moving least
//!    squares, Lee 2000), then once more with the window centred on where it moved, so a
//!    sample in the band's tail fits the same stretch as those in its middle. A sample
//!    farther than three residuals from the parabola is an outlier of it, and so is one
//!    whose window holds samples more than three times more sparsely (per unit of its
//!    radius) than the windows of the samples it holds ([`SPARSER`]): beside a noisy
//!    band an outlier's window holds ten samples of the band's tail and sees a curve
//!    there, where the band's own windows hold tens; along a curve an end's window is
//!    the sparsest, at half its neighbours'.
//! 3. *Tree.* The moved samples' Euclidean minimum spanning tree over their Delaunay
//!    edges, each edge within both ends' windows: along a curve the nearest moved
//!    samples are its neighbours, across a channel the other wall is farther.
//! 4. *Spurs.* A branch from a free end to a fork shorter than the fork's window is
//!    noise across the band, not a stroke, and goes: the shortest first, each checked
//!    again when its turn comes, as of two short branches at one fork the longer is the
//!    curve's end once the shorter is gone (in the samples' order they ate curves' ends
//!    one fork at a time).
//! 5. *Ends.* An end's window is the largest of its branch's first ten vertices' (one
//!    window's samples): an end is often a sample of the band's tail whose own window
//!    qualified early, by chance. Within two such windows: two free ends facing each
//!    other are joined (a loop's tree misses one edge; a gap the sampling left), each
//!    with the one nearest both ends' lines (a curve continues along its tangent; at a
//!    crossing the other stroke's arms are nearer, beside the line); then the
//!    ends left meet at corners (a corner's own samples see two walls, so the tree stops
//!    short of it on both sides), where a sample lies within the corner's window (its
//!    own samples are there); then an end continues into the nearest curve vertex ahead
//!    of it (within 60 degrees of its direction: a stroke running into another), unless
//!    its branch, from a fork or to its chain's other end, is shorter than two windows
//!    (below the graph's resolution along a curve, step 6: the tip an acute corner
//!    leaves, or a few samples whose windows saw a curve by chance, which would run
//!    across empty space as a whisker). Corners before T's: two free ends that meet
//!    are one curve turning,
//!    and a T makes a fork, which no closed outline has (at a concave corner one wall's
//!    end ran into the other wall's side before the corner was tried).
//!    Never into its own branch within `2 pi` windows.
//! 6. *Curves.* Two chains between the same two forks but the shortest go where they
//!    are shorter than `2 pi` windows (a bubble). Spurs go again, now those shorter than
//!    two windows: two windows is the graph's resolution along a curve (a gap that short
//!    is closed in step 5, so a branch that short cannot be told from the sampling), and
//!    at an acute corner the two walls' samples, within a window of each other, fall onto
//!    one line and leave such a spur at the tip. Two forks joined by a chain shorter than
//!    two windows are one junction (below that resolution the tree cannot tell where
//!    strokes meet; at a crossing it makes two T's). Connected pieces of fewer than ten
//!    vertices (one window's samples) or shorter than two of their windows go; the rest
//!    are chains between vertices of degree
//!    other than two, the forks junctions. A chain from a free end shorter than its window
//!    holds no curve. A closed chain turns counter-clockwise, clockwise inside an odd
//!    number of the others (a hole).

use rayon::prelude::*;

use crate::disjoint::root;
use crate::distance::DistanceField;
use crate::geom::{add, crossing, dist, dot, scale, sub, Point, Polyline};
use crate::mesh::metric::{fit_within, largest_window, sees_a_curve, AREA_SHARE, SHEET_SAMPLES};
use crate::repair::strokes::Junction;

/// A sample farther than this many residuals from the curve its window sees is an
/// outlier of it (three standard deviations of Gaussian noise hold 99.7% of a band).
const OUTLYING: f64 = 3.0;
/// A sample whose window holds samples along its curve this many times more sparsely
/// than the windows of the samples it holds (the median of theirs) is an outlier
/// beside a curve, not on it: an end's window holds its ten on one side, half its
/// neighbours' density, and a count of about ten varies by a third (`1 / sqrt 10`), so
/// along a curve the ratio stays below `2 * 4 / 3`; an outlier beside a band holds ten
/// samples of the band's tail in a window where the band's own hold tens.
const SPARSER: f64 = 3.0;
/// Edges at a merged fork, at most: as many as a Euclidean minimum spanning tree's
/// vertex has (three strokes through one point), far from a star.
const MAX_FORK: usize = 6;
/// An end continues across at most this many of its windows: the longest gap of a
/// random sampling of `n` samples is about `ln n` mean spacings (under 10 below 20,000
/// samples), and a window holds ten samples, about five spacings either side.
const GAP_WINDOWS: f64 = 2.0;
/// An end continues to a vertex ahead of it within this cosine of its direction (60
/// degrees): a loop's two ends face each other across the edge the tree left out.
const AHEAD_COS: f64 = 0.5;
/// An end's continuation skips vertices of its own branch within this many windows
/// along the tree (2 pi): a window sees a curve only where it bends over more than the
/// window, so no loop it sees is shorter than a circle of one window's radius, and a
/// shorter one would be a bubble round the band's own samples.
const OWN_BRANCH_WINDOWS: f64 = std::f64::consts::TAU;

/// What [`graph_curves`] draws.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Graphed {
    /// The curves, in the field's coordinates.
    pub polylines: Vec<Polyline>,
    /// Where three or more curves meet (indices into `polylines`).
    pub junctions: Vec<Junction>,
}

/// The curves through the samples of `field`, with noise of standard deviation `noise`
/// (the noise measurement's, [`crate::mesh::metric`]) and the accuracy bound `bound`
/// (`3 noise + 2 hmin`), by the steps of the module's doc: each sample's window from the
/// radius that holds ten samples up to [`window_cap`], or at that radius where it is
/// larger and its samples lie within `bound` of their fit.
pub fn graph_curves(field: &DistanceField, noise: f64, bound: f64) -> Graphed {
    let radii = ten_sample_radii(field);
    let thinned = thinned(field, &radii, noise);
    let (field, radii) = match &thinned {
        Some(kept) => (kept, ten_sample_radii(kept)),
        None => (field, radii),
    };
    let nodes = settled(field, &radii, window_cap(field, &radii), bound);
    // Windows pass by chance in scattered points, at the edges of the area they fill.
    if nodes.len() < 2 || (nodes.len() as f64) < AREA_SHARE * field.points().len() as f64 {
        return Graphed::default();
    }
    let mut q: Vec<Point> = nodes.iter().map(|n| n.at).collect();
    let mut r: Vec<f64> = nodes.iter().map(|n| n.window).collect();
    let tangents: Vec<Point> = nodes.iter().map(|n| n.tangent).collect();
    let Ok(q_field) = DistanceField::new(&q) else {
        return Graphed::default();
    };
    let mut adj = spanning_tree(&q, &r);
    prune_spurs(&q, &r, &mut adj, 1.0);
    continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Facing);
    meet_at_corners(&mut q, &mut r, &tangents, field, &q_field, &mut adj);
    continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Ahead);
    pop_bubbles(&q, &r, &mut adj);
    // An end continued into its curve's side leaves the stub past it a spur.
    prune_spurs(&q, &r, &mut adj, GAP_WINDOWS);
    merge_close_forks(&mut q, &r, &q_field, &mut adj);
    drop_small_components(&q, &r, &mut adj);
    chains(&q, &r, &adj)
}

/// Step 0, density: where a typical sample's ten nearest lie within half the noise `noise`, a
/// subsample in which they lie about that far: every sample kept with one probability
/// (the ratio of the two radii's squares, as the count within a radius goes with its
/// area), so the noise band's profile across the curve is the data's. A window spans
/// four residuals (about three noise deviations) before it sees a curve; ten samples
/// within half a deviation put tens in it, and more sharpen no fit whose residual the
/// noise sets, but they cost every window's fit: without it the simulator's strokes with
/// 100,000 samples at a noise of 2% of the box took 16 s in this stage, with it 1.6 s. `None` where the samples are sparser than that
/// (every glyph of the corpus), or there is no noise to thin to.
/// `radii` are the samples' [`ten_sample_radii`].
fn thinned(field: &DistanceField, radii: &[f64], noise: f64) -> Option<DistanceField> {
    // No noise (or none measured, NaN) leaves nothing to thin to.
    if radii.is_empty() || noise.is_nan() || noise <= 0.0 {
        return None;
    }
    let keep = (typical(radii) / (0.5 * noise)).powi(2);
    if keep.is_nan() || keep >= 1.0 {
        return None;
    }
    // A fixed hash of each sample's index (splitmix64): the same subsample every run.
    let kept: Vec<Point> = field
        .points()
        .iter()
        .enumerate()
        .filter(|&(i, _)| {
            let mut z = (i as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            ((z >> 11) as f64) < keep * (1u64 << 53) as f64
        })
        .map(|(_, &p)| p)
        .collect();
    (kept.len() > SHEET_SAMPLES)
        .then(|| DistanceField::new(&kept).ok())
        .flatten()
}

/// The largest window (step 1): the noise measurement's ([`largest_window`]), or
/// [`SPARSER`] times the radius that holds a typical sample's ten nearest (the median
/// over the samples) where that is wider. No window smaller than ten samples' holds a
/// fit, so where the sampling is sparser than the noise measurement's largest window
/// allows ten samples, every sample would be lost; a sample that needs a window more
/// than [`SPARSER`] times a typical one's to hold ten is an outlier by the density test
/// of step 2 anyway.
/// `radii` are the samples' [`ten_sample_radii`].
fn window_cap(field: &DistanceField, radii: &[f64]) -> f64 {
    largest_window(field).max(SPARSER * typical(radii))
}

/// A typical sample's ten-sample radius: the median of `radii` (0 for none).
fn typical(radii: &[f64]) -> f64 {
    if radii.is_empty() {
        return 0.0;
    }
    let mut sorted = radii.to_vec();
    let mid = sorted.len() / 2;
    *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Per sample, the radius that holds its [`SHEET_SAMPLES`] nearest: where its window
/// starts.
fn ten_sample_radii(field: &DistanceField) -> Vec<f64> {
    let pts = field.points();
    pts.par_iter()
        .map_init(Vec::new, |idx: &mut Vec<u32>, &c| {
            field.nearest_k(c, SHEET_SAMPLES, idx);
            idx.last().map_or(0.0, |&j| dist(c, pts[j as usize]))
        })
        .collect()
}

/// Step 1 and 2: each sample that sees a curve, moved onto it, with its window's
/// radius; sorted and without duplicates (the order [`DistanceField::new`] keeps).
/// Windows start at the samples' `radii` ([`ten_sample_radii`]).
fn settled(field: &DistanceField, radii: &[f64], r_max: f64, bound: f64) -> Vec<Node> {
    let each: Vec<Option<Node>> = field
        .points()
        .par_iter()
        .zip(radii)
        .map_init(
            || (Vec::new(), Vec::new()),
            |(idx, sel): &mut (Vec<u32>, Vec<Point>), (&c, &r)| {
                let mut r = r;
                // A sample sparser than the cap is tried at its own ten, where they must
                // lie on their fit within the accuracy bound, as a sparse stretch of a
                // curve's do and ten scattered points' do not.
                let beyond = r > r_max;
                while r <= r_max || beyond {
                    let f = fit_within(field, c, r, idx, sel);
                    if sees_a_curve(&f, idx.len(), r) && (!beyond || f.residual <= bound) {
                        let p = foot(c, sel, f.normal, outlying(f.residual, r))?;
                        // Once more from where it moved, at the same radius.
                        let g = fit_within(field, p, r, idx, sel);
                        let (p, normal) = if sees_a_curve(&g, idx.len(), r) {
                            let q = foot(p, sel, g.normal, outlying(g.residual, r));
                            q.map_or((p, f.normal), |q| (q, g.normal))
                        } else {
                            (p, f.normal)
                        };
                        return Some(Node {
                            at: p,
                            held: idx.len() as f64,
                            window: r,
                            tangent: [normal[1], -normal[0]],
                        });
                    }
                    if beyond {
                        break;
                    }
                    r *= 1.25;
                }
                None
            },
        )
        .collect();
    // Step 2's density test: a sample's window holds samples along its curve as
    // densely as theirs do.
    let pts = field.points();
    let mut out: Vec<Node> = (0..pts.len())
        .into_par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(idx, density): &mut (Vec<u32>, Vec<f64>), i| {
                let n = each[i]?;
                field.within(pts[i], n.window, idx);
                density.clear();
                density.extend(
                    idx.iter()
                        .filter(|&&j| j as usize != i)
                        .filter_map(|&j| each[j as usize].map(|m| m.density())),
                );
                if density.is_empty() {
                    return None;
                }
                let mid = density.len() / 2;
                let median = *density.select_nth_unstable_by(mid, f64::total_cmp).1;
                (SPARSER * n.density() >= median).then_some(n)
            },
        )
        .flatten()
        .collect();
    out.sort_unstable_by(|a, b| {
        a.at[0]
            .total_cmp(&b.at[0])
            .then(a.at[1].total_cmp(&b.at[1]))
    });
    out.dedup_by(|a, b| a.at == b.at);
    out
}

/// A sample moved onto the curve its window sees.
#[derive(Clone, Copy, Debug)]
struct Node {
    /// Where it moved.
    at: Point,
    /// Its window's radius.
    window: f64,
    /// The samples its window held (centred where the sample moved).
    held: f64,
    /// The curve's unit tangent there (either way).
    tangent: Point,
}

impl Node {
    /// The samples its window held per unit of its radius: along a curve, its linear
    /// density.
    fn density(&self) -> f64 {
        self.held / self.window
    }
}

/// How far from its window's fit (residual `residual`, radius `r`) a sample may lie
/// and not be an outlier of it: [`OUTLYING`] residuals, and at least a billionth of the
/// window, the fit's own rounding on samples that lie exactly on a curve.
fn outlying(residual: f64, r: f64) -> f64 {
    (OUTLYING * residual).max(1e-9 * r)
}

/// The foot on the parabola fitted to `pts` in the frame at `c` with unit `normal`
/// (least squares of the offset along the normal on the position along the tangent):
/// `c` moved along the normal to the parabola's value there, or `None` where the fit is
/// singular or its foot lies farther than `within`.
fn foot(c: Point, pts: &[Point], normal: Point, within: f64) -> Option<Point> {
    let t = [normal[1], -normal[0]];
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for &p in pts {
        let d = sub(p, c);
        let (s, h) = (dot(d, t), dot(d, normal));
        let row = nalgebra::Vector3::new(1.0, s, s * s);
        ata += row * row.transpose();
        atb += row * h;
    }
    let x = ata.lu().solve(&atb)?;
    (x[0].is_finite() && x[0].abs() <= within).then(|| add(c, scale(normal, x[0])))
}

/// Step 3: the minimum spanning forest of the Delaunay edges of `q` no longer than
/// both ends' windows `r`, as adjacency lists.
fn spanning_tree(q: &[Point], r: &[f64]) -> Vec<Vec<u32>> {
    use spade::{DelaunayTriangulation, Point2, Triangulation};
    let n = q.len();
    let mut adj = vec![Vec::new(); n];
    // spade refuses a coordinate nearer zero than 2^-142 (a sample on an axis moved
    // by a rounding error onto the curve): such a coordinate is zero.
    let verts: Vec<Point2<f64>> = q
        .iter()
        .map(|p| spade::mitigate_underflow(Point2::new(p[0], p[1])))
        .collect();
    let Ok(dt) = DelaunayTriangulation::<Point2<f64>>::bulk_load_stable(verts) else {
        return adj;
    };
    let mut edges: Vec<(f64, u32, u32)> = dt
        .undirected_edges()
        .filter_map(|e| {
            let [a, b] = e.vertices().map(|v| v.fix().index() as u32);
            let d = dist(q[a as usize], q[b as usize]);
            (d <= r[a as usize].min(r[b as usize])).then_some((d, a, b))
        })
        .collect();
    edges.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for (_, a, b) in edges {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent[ra as usize] = rb;
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
    }
    adj
}

/// The branch from the free end `leaf` to the first vertex of degree other than two
/// (its path, the vertex last) and its length.
fn branch(q: &[Point], adj: &[Vec<u32>], leaf: u32) -> (Vec<u32>, f64) {
    let mut path = vec![leaf];
    let (mut prev, mut cur, mut len) = (u32::MAX, leaf, 0.0);
    loop {
        let next = adj[cur as usize].iter().copied().find(|&x| x != prev);
        let Some(next) = next else { break };
        len += dist(q[cur as usize], q[next as usize]);
        path.push(next);
        (prev, cur) = (cur, next);
        if adj[cur as usize].len() != 2 {
            break;
        }
    }
    (path, len)
}

fn unlink(adj: &mut [Vec<u32>], a: u32, b: u32) {
    adj[a as usize].retain(|&x| x != b);
    adj[b as usize].retain(|&x| x != a);
}

/// Steps 4 and 6: branches from a free end to a fork shorter than `windows` of the
/// fork's window go, until none does (each round removes a branch or stops; bounded by
/// the vertices).
fn prune_spurs(q: &[Point], r: &[f64], adj: &mut [Vec<u32>], windows: f64) {
    loop {
        // Shortest first, each checked again when its turn comes: of two short
        // branches at one fork, the longer is the curve's end once the shorter is gone.
        let mut spurs: Vec<(f64, u32)> = (0..q.len() as u32)
            .filter(|&leaf| adj[leaf as usize].len() == 1)
            .filter_map(|leaf| {
                let (path, len) = branch(q, adj, leaf);
                let fork = *path.last().expect("a branch holds its end");
                (adj[fork as usize].len() >= 3 && len < windows * r[fork as usize])
                    .then_some((len, leaf))
            })
            .collect();
        if spurs.is_empty() {
            break;
        }
        spurs.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, leaf) in spurs {
            if adj[leaf as usize].len() != 1 {
                continue;
            }
            let (path, len) = branch(q, adj, leaf);
            let fork = *path.last().expect("a branch holds its end");
            if adj[fork as usize].len() >= 3 && len < windows * r[fork as usize] {
                for w in path.windows(2) {
                    unlink(adj, w[0], w[1]);
                }
            }
        }
    }
}

/// Step 5, one `pass` of it: each free end continued to a vertex ahead of it within
/// [`GAP_WINDOWS`] windows (a facing end the one nearest both ends' lines, a curve's
/// side the nearest), not of its own branch within [`OWN_BRANCH_WINDOWS`] windows,
/// where the continuation crosses no edge; into a curve's side only from a branch the
/// graph resolves ([`below_resolution`]).
fn continue_ends(
    q: &[Point],
    r: &[f64],
    tangents: &[Point],
    q_field: &DistanceField,
    adj: &mut [Vec<u32>],
    pass: Pass,
) {
    // The crossing check finds an edge by its ends within the longest edge: each join
    // keeps it the longest so far.
    let mut longest = longest_edge(q, adj);
    let mut near = Vec::new();
    let mut stamp = vec![u32::MAX; q.len()];
    let mut stack = Vec::new();
    // Facing: two free ends that face each other (a loop's, or a gap's two sides).
    // Ahead: an end into any vertex ahead (a stroke that runs into another).
    for u in 0..q.len() as u32 {
        if adj[u as usize].len() != 1 {
            continue;
        }
        let ru = end_window(r, adj, u);
        if matches!(pass, Pass::Ahead) && below_resolution(q, adj, u, ru) {
            continue;
        }
        own_branch(q, adj, u, OWN_BRANCH_WINDOWS * ru, &mut stamp, &mut stack);
        let dir = end_direction(q, r, tangents, adj, u);
        q_field.within(q[u as usize], GAP_WINDOWS * ru, &mut near);
        let best = near
            .iter()
            .copied()
            // A vertex takes a continuation where it is a curve's end or middle, not
            // at a fork: no vertex is a star.
            .filter(|&v| stamp[v as usize] != u && (1..=2).contains(&adj[v as usize].len()))
            .filter(|&v| {
                let e = sub(q[v as usize], q[u as usize]);
                let ahead = |d: Point, e: Point| dot(e, d) >= AHEAD_COS * dot(e, e).sqrt();
                let free = adj[v as usize].len() == 1;
                match pass {
                    Pass::Facing => {
                        free && ahead(dir, e)
                            && ahead(end_direction(q, r, tangents, adj, v), scale(e, -1.0))
                    }
                    Pass::Ahead => ahead(dir, e),
                }
            })
            .min_by(|&a, &b| {
                let cost = |v: u32| match pass {
                    // A curve continues across a gap along its tangent: the other end
                    // lies on the end's line, where at a crossing the other stroke's
                    // arms lie beside it, nearer but off the line.
                    Pass::Facing => {
                        let e = sub(q[v as usize], q[u as usize]);
                        let dv = end_direction(q, r, tangents, adj, v);
                        crate::geom::cross(dir, e)
                            .abs()
                            .max(crate::geom::cross(dv, e).abs())
                    }
                    Pass::Ahead => dist(q[u as usize], q[v as usize]),
                };
                cost(a).total_cmp(&cost(b))
            });
        let Some(v) = best else { continue };
        let (a, b) = (q[u as usize], q[v as usize]);
        let crosses = crosses_an_edge(q, q_field, adj, a, b, &[u, v], longest, &mut near);
        if !crosses {
            adj[u as usize].push(v);
            adj[v as usize].push(u);
            longest = longest.max(dist(a, b));
        }
    }
}

/// Whether the free end `u` (its end window `ru`) is the end of a branch shorter than
/// [`GAP_WINDOWS`] windows, from a fork or to the chain's other end: below the graph's
/// resolution along a curve (step 6), it is no stroke that runs into another. From a
/// fork it is the tip an acute corner leaves past the corner; alone, a few samples
/// whose windows saw a curve by chance (outliers near each other, or beside a band),
/// which as a T would draw a whisker from a curve into empty space.
fn below_resolution(q: &[Point], adj: &[Vec<u32>], u: u32, ru: f64) -> bool {
    branch(q, adj, u).1 < GAP_WINDOWS * ru
}

/// Marks with `u` in `stamp` the vertices within `limit` of the end `u` along the tree.
fn own_branch(
    q: &[Point],
    adj: &[Vec<u32>],
    u: u32,
    limit: f64,
    stamp: &mut [u32],
    stack: &mut Vec<(u32, f64)>,
) {
    stamp[u as usize] = u;
    stack.clear();
    stack.push((u, 0.0));
    while let Some((a, da)) = stack.pop() {
        for &b in &adj[a as usize] {
            let db = da + dist(q[a as usize], q[b as usize]);
            if stamp[b as usize] != u && db <= limit {
                stamp[b as usize] = u;
                stack.push((b, db));
            }
        }
    }
}

/// The longest edge of `adj`.
fn longest_edge(q: &[Point], adj: &[Vec<u32>]) -> f64 {
    (0..q.len())
        .flat_map(|a| adj[a].iter().map(move |&b| (a, b)))
        .map(|(a, b)| dist(q[a], q[b as usize]))
        .fold(0.0, f64::max)
}

/// Whether the segment `a b` crosses an edge of `adj` but those at the vertices `ends`:
/// such an edge has an end within half its length and the `longest` edge of its
/// middle.
#[allow(clippy::too_many_arguments)]
fn crosses_an_edge(
    q: &[Point],
    q_field: &DistanceField,
    adj: &[Vec<u32>],
    a: Point,
    b: Point,
    ends: &[u32],
    longest: f64,
    near: &mut Vec<u32>,
) -> bool {
    let mid = scale(add(a, b), 0.5);
    q_field.within(mid, 0.5 * dist(a, b) + longest, near);
    near.iter().any(|&x| {
        adj[x as usize].iter().any(|&y| {
            !ends.contains(&x)
                && !ends.contains(&y)
                && crossing(a, b, q[x as usize], q[y as usize]).is_some()
        })
    })
}

/// Step 5, last: the free ends left meet at corners. A corner's own samples see two
/// walls, not a curve, so the tree stops short of it on both sides; two free ends
/// whose directions meet ahead of both, within [`GAP_WINDOWS`] windows of each, are
/// joined through that point (a new vertex, the corner) where a sample of `field` lies
/// within the corner's window of it, and two within [`GAP_WINDOWS`] windows whose lines
/// do not meet there are joined directly. Not ends of one branch within
/// [`OWN_BRANCH_WINDOWS`] windows, nor across an edge.
fn meet_at_corners(
    q: &mut Vec<Point>,
    r: &mut Vec<f64>,
    tangents: &[Point],
    field: &DistanceField,
    q_field: &DistanceField,
    adj: &mut Vec<Vec<u32>>,
) {
    // As in `continue_ends`; a corner is not in `q_field`, so its edges are found by
    // their other ends.
    let mut longest = longest_edge(q, adj);
    let n = q.len();
    let mut near = Vec::new();
    let mut stamp = vec![u32::MAX; n];
    let mut stack = Vec::new();
    for u in 0..n as u32 {
        if adj[u as usize].len() != 1 {
            continue;
        }
        let ru = end_window(r, adj, u);
        own_branch(q, adj, u, OWN_BRANCH_WINDOWS * ru, &mut stamp, &mut stack);
        let du = end_direction(q, r, tangents, adj, u);
        q_field.within(q[u as usize], 2.0 * GAP_WINDOWS * ru, &mut near);
        let mut best: Option<(f64, u32, Option<Point>)> = None;
        for &v in &near {
            if v == u || stamp[v as usize] == u || adj[v as usize].len() != 1 {
                continue;
            }
            let (pu, pv) = (q[u as usize], q[v as usize]);
            let rv = end_window(r, adj, v);
            let dv = end_direction(q, r, tangents, adj, v);
            // Where the two ends' lines meet: pu + s du = pv + t dv.
            let den = crate::geom::cross(du, dv);
            let corner = (den.abs() > 1e-12).then(|| {
                let w = sub(pv, pu);
                (
                    crate::geom::cross(w, dv) / den,
                    crate::geom::cross(w, du) / den,
                )
            });
            // A corner lies where samples are: its own samples, which see two walls and
            // so are in no branch, are within its window of it. Two ends' lines that
            // meet in empty space (an end's direction is its window's tangent, and two
            // windows ahead a degree of it is a window off) meet at no corner.
            let joint = match corner {
                Some((s, t))
                    if s >= 0.0
                        && t >= 0.0
                        && s <= GAP_WINDOWS * ru
                        && t <= GAP_WINDOWS * rv
                        && field.distance(add(pu, scale(du, s))) <= 0.5 * (ru + rv) =>
                {
                    Some(Some(add(pu, scale(du, s))))
                }
                _ if dist(pu, pv) <= GAP_WINDOWS * ru => Some(None),
                _ => None,
            };
            if let Some(joint) = joint {
                let d = dist(pu, pv);
                if best.is_none_or(|b| d < b.0) {
                    best = Some((d, v, joint));
                }
            }
        }
        let Some((_, v, joint)) = best else { continue };
        let (pu, pv) = (q[u as usize], q[v as usize]);
        // A segment from an end meets that end's edges there and crosses no other.
        let crosses = |a: Point, b: Point, ends: &[u32], near: &mut Vec<u32>| {
            crosses_an_edge(q, q_field, adj, a, b, ends, longest, near)
        };
        match joint {
            Some(c) => {
                if crosses(pu, c, &[u], &mut near) || crosses(c, pv, &[v], &mut near) {
                    continue;
                }
                longest = longest.max(dist(pu, c)).max(dist(c, pv));
                let k = q.len() as u32;
                let rv = end_window(r, adj, v);
                q.push(c);
                r.push(0.5 * (ru + rv));
                adj.push(vec![u, v]);
                stamp.push(u32::MAX);
                adj[u as usize].push(k);
                adj[v as usize].push(k);
            }
            None => {
                if crosses(pu, pv, &[u, v], &mut near) {
                    continue;
                }
                longest = longest.max(dist(pu, pv));
                adj[u as usize].push(v);
                adj[v as usize].push(u);
            }
        }
    }
}

/// The window of the curves at the fork `v`: the largest of its arms' first
/// [`SHEET_SAMPLES`] vertices' windows, as for an end ([`end_window`]).
fn fork_window(r: &[f64], adj: &[Vec<u32>], v: u32) -> f64 {
    let mut most = r[v as usize];
    for &w in &adj[v as usize] {
        let (mut prev, mut cur) = (v, w);
        for _ in 0..SHEET_SAMPLES {
            most = most.max(r[cur as usize]);
            if adj[cur as usize].len() != 2 {
                break;
            }
            let next = adj[cur as usize][usize::from(adj[cur as usize][0] == prev)];
            (prev, cur) = (cur, next);
        }
    }
    most
}

/// The window of the curve at the free end `u`: the largest of its branch's first
/// [`SHEET_SAMPLES`] vertices' windows (one window's samples). An end is often a sample
/// of the band's tail whose own window qualified early, by chance, at a fraction of the
/// window its curve's samples need.
fn end_window(r: &[f64], adj: &[Vec<u32>], u: u32) -> f64 {
    let (mut prev, mut cur, mut most) = (u32::MAX, u, r[u as usize]);
    for _ in 1..SHEET_SAMPLES {
        let Some(next) = adj[cur as usize].iter().copied().find(|&x| x != prev) else {
            break;
        };
        most = most.max(r[next as usize]);
        if adj[next as usize].len() != 2 {
            break;
        }
        (prev, cur) = (cur, next);
    }
    most
}

/// The passes of [`continue_ends`].
#[derive(Clone, Copy)]
enum Pass {
    Facing,
    Ahead,
}

/// The curve's direction at the free end `u`: its window's tangent, turned away from
/// the mean of its branch's vertices within [`OWN_BRANCH_WINDOWS`] windows along the
/// tree (their mean, not one vertex, as the tree may hook back by a few samples at its
/// end, where the windows are one-sided).
fn end_direction(q: &[Point], r: &[f64], tangents: &[Point], adj: &[Vec<u32>], u: u32) -> Point {
    let (mut sum, mut count) = (q[u as usize], 1.0);
    let (mut prev, mut cur, mut len) = (u32::MAX, u, 0.0);
    while let Some(next) = adj[cur as usize].iter().copied().find(|&x| x != prev) {
        len += dist(q[cur as usize], q[next as usize]);
        if len > OWN_BRANCH_WINDOWS * r[u as usize] || adj[next as usize].len() > 2 {
            break;
        }
        sum = add(sum, q[next as usize]);
        count += 1.0;
        (prev, cur) = (cur, next);
    }
    let back = sub(q[u as usize], scale(sum, 1.0 / count));
    let t = tangents[u as usize];
    if dot(t, back) >= 0.0 {
        t
    } else {
        scale(t, -1.0)
    }
}

/// Every chain of vertices of degree two between two forks (vertices of three or more
/// edges), once, from its lower fork, with its length; a loop from a fork back to itself
/// is none.
fn chains_between_forks(q: &[Point], adj: &[Vec<u32>]) -> Vec<(f64, Vec<u32>)> {
    let mut out = Vec::new();
    for v in 0..q.len() as u32 {
        if adj[v as usize].len() < 3 {
            continue;
        }
        for &w in &adj[v as usize] {
            let mut path = vec![v, w];
            let (mut prev, mut cur) = (v, w);
            while adj[cur as usize].len() == 2 {
                let next = adj[cur as usize][usize::from(adj[cur as usize][0] == prev)];
                path.push(next);
                (prev, cur) = (cur, next);
            }
            if adj[cur as usize].len() >= 3 && v < cur {
                let len = path
                    .windows(2)
                    .map(|e| dist(q[e[0] as usize], q[e[1] as usize]))
                    .sum();
                out.push((len, path));
            }
        }
    }
    out
}

/// Two or more chains between the same two forks, but for the shortest, that are
/// shorter than [`OWN_BRANCH_WINDOWS`] windows go: they are one stretch of curve drawn
/// twice round the band's samples (a bubble), no loop a window could see.
fn pop_bubbles(q: &[Point], r: &[f64], adj: &mut [Vec<u32>]) {
    // Chains by their two forks: (length, vertices).
    type Chains = Vec<(f64, Vec<u32>)>;
    let mut by_ends: std::collections::HashMap<(u32, u32), Chains> = Default::default();
    for (len, path) in chains_between_forks(q, adj) {
        let ends = (path[0], *path.last().expect("a chain has two ends"));
        by_ends.entry(ends).or_default().push((len, path));
    }
    for ((a, b), mut paths) in by_ends {
        if paths.len() < 2 {
            continue;
        }
        paths.sort_by(|x, y| x.0.total_cmp(&y.0));
        let window = r[a as usize].max(r[b as usize]);
        for (len, path) in paths.into_iter().skip(1) {
            if len < OWN_BRANCH_WINDOWS * window {
                for e in path.windows(2) {
                    unlink(adj, e[0], e[1]);
                }
            }
        }
    }
}

/// Two forks joined by a chain shorter than [`GAP_WINDOWS`] windows are one junction:
/// below the graph's resolution along a curve (step 6) the tree cannot tell where the
/// strokes meet, and where two strokes cross it links their samples as two T's a few
/// samples apart. The shortest first, each chain goes and its forks become one vertex
/// at the chain's middle, where the merged fork's edges cross no other edge.
fn merge_close_forks(q: &mut [Point], r: &[f64], q_field: &DistanceField, adj: &mut [Vec<u32>]) {
    let mut chains: Vec<(f64, Vec<u32>)> = chains_between_forks(q, adj)
        .into_iter()
        .filter(|(len, path)| {
            let (a, b) = (path[0], *path.last().expect("a chain has two ends"));
            *len < GAP_WINDOWS * 0.5 * (fork_window(r, adj, a) + fork_window(r, adj, b))
        })
        .collect();
    chains.sort_by(|x, y| x.0.total_cmp(&y.0));
    // `q_field` finds vertices where they were: a merged fork has moved by at most
    // `slack`, and an edge is found by an end within the longest edge.
    let mut longest = longest_edge(q, adj);
    let mut slack = 0.0f64;
    let mut near = Vec::new();
    for (_, path) in chains {
        let (a, b) = (path[0], *path.last().expect("a chain has two ends"));
        let intact = path.windows(2).all(|e| adj[e[0] as usize].contains(&e[1]))
            && path[1..path.len() - 1]
                .iter()
                .all(|&v| adj[v as usize].len() == 2)
            && adj[a as usize].len() >= 3
            && adj[b as usize].len() >= 3;
        if !intact {
            continue;
        }
        let mid = scale(
            path.iter().fold([0.0, 0.0], |s, &v| add(s, q[v as usize])),
            1.0 / path.len() as f64,
        );
        let mut ends: Vec<u32> = adj[a as usize]
            .iter()
            .chain(&adj[b as usize])
            .copied()
            .filter(|x| !path.contains(x))
            .collect();
        ends.sort_unstable();
        ends.dedup();
        // No more edges than a spanning tree's vertex has: no star.
        if ends.len() > MAX_FORK {
            continue;
        }
        // Each new edge meets the chain's edges (which go) and its far end's edges
        // there, and crosses no other.
        let crosses = ends.iter().any(|&x| {
            let at: Vec<u32> = path.iter().copied().chain([x]).collect();
            let p = q[x as usize];
            crosses_an_edge(q, q_field, adj, mid, p, &at, longest + slack, &mut near)
        });
        if crosses {
            continue;
        }
        for e in path.windows(2) {
            unlink(adj, e[0], e[1]);
        }
        for &x in &ends {
            unlink(adj, b, x);
            if !adj[a as usize].contains(&x) {
                adj[a as usize].push(x);
                adj[x as usize].push(a);
            }
        }
        slack = slack
            .max(dist(mid, q[a as usize]))
            .max(dist(mid, q[b as usize]));
        q[a as usize] = mid;
        longest = ends
            .iter()
            .map(|&x| dist(mid, q[x as usize]))
            .fold(longest, f64::max);
    }
}

/// Connected pieces of fewer than [`SHEET_SAMPLES`] vertices, or shorter than
/// [`GAP_WINDOWS`] of their largest window, go: a curve holds at least the samples one
/// window needs to see it and is no shorter than the graph's resolution along a curve
/// (step 6); windows that pass by chance in scattered points (a few in a hundred) link
/// into such crumbs, and samples piled onto one spot by their moves make a crumb of ten
/// vertices a fraction of a window long.
fn drop_small_components(q: &[Point], r: &[f64], adj: &mut [Vec<u32>]) {
    let n = adj.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for (a, links) in adj.iter().enumerate() {
        for &b in links {
            let (ra, rb) = (root(&mut parent, a as u32), root(&mut parent, b));
            if ra != rb {
                parent[ra as usize] = rb;
            }
        }
    }
    let mut size = vec![0usize; n];
    let mut length = vec![0.0f64; n];
    let mut window = vec![0.0f64; n];
    for a in 0..n as u32 {
        let ra = root(&mut parent, a) as usize;
        size[ra] += 1;
        window[ra] = window[ra].max(r[a as usize]);
        // Each edge is counted from both its ends.
        length[ra] += 0.5
            * adj[a as usize]
                .iter()
                .map(|&b| dist(q[a as usize], q[b as usize]))
                .sum::<f64>();
    }
    for a in 0..n as u32 {
        let ra = root(&mut parent, a) as usize;
        if size[ra] < SHEET_SAMPLES || length[ra] < GAP_WINDOWS * window[ra] {
            adj[a as usize].clear();
        }
    }
}

/// Step 6: the chains between vertices of degree other than two, and the cycles left;
/// pieces shorter than their first vertex's window go. The forks are junctions.
fn chains(q: &[Point], r: &[f64], adj: &[Vec<u32>]) -> Graphed {
    let n = q.len();
    let mut used = std::collections::HashSet::new();
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut pieces: Vec<(Vec<u32>, bool)> = Vec::new();
    let walk = |start: u32, next: u32, used: &mut std::collections::HashSet<(u32, u32)>| {
        let mut path = vec![start];
        let (mut prev, mut cur) = (start, next);
        used.insert(key(start, next));
        loop {
            path.push(cur);
            if adj[cur as usize].len() != 2 || cur == start {
                break;
            }
            let Some(nx) = adj[cur as usize]
                .iter()
                .copied()
                .find(|&x| x != prev && !used.contains(&key(cur, x)))
            else {
                break;
            };
            used.insert(key(cur, nx));
            (prev, cur) = (cur, nx);
        }
        path
    };
    // From the ends and forks first, then round the cycles left; a piece that comes
    // back to where it started (a cycle, or a loop through a fork) is closed.
    let starts = (0..n as u32)
        .filter(|&v| adj[v as usize].len() != 2)
        .chain(0..n as u32);
    for v in starts {
        for &w in &adj[v as usize] {
            if !used.contains(&key(v, w)) {
                let mut path = walk(v, w, &mut used);
                let closed = path.len() > 3 && path.first() == path.last();
                if closed {
                    path.pop();
                }
                pieces.push((path, closed));
            }
        }
    }
    let mut out = Graphed::default();
    let mut forks: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    for (path, closed) in pieces {
        let pts: Vec<Point> = path.iter().map(|&i| q[i as usize]).collect();
        let len: f64 = pts.windows(2).map(|w| dist(w[0], w[1])).sum();
        let ends_at_fork = |i: u32| adj[i as usize].len() >= 3;
        let first = path[0];
        let last = *path.last().expect("a piece has two vertices");
        // A short piece between two forks is the curve itself; one with a free end
        // shorter than its window holds no curve.
        let between_forks = ends_at_fork(first) && ends_at_fork(last);
        if !closed && !between_forks && len < r[first as usize] {
            continue;
        }
        let k = out.polylines.len();
        if !closed {
            for end in [first, last] {
                if ends_at_fork(end) {
                    forks.entry(end).or_default().push(k);
                }
            }
        }
        out.polylines.push(Polyline {
            closed,
            points: pts,
        });
    }
    out.junctions = forks
        .into_iter()
        .filter(|(_, ps)| ps.len() >= 2)
        .map(|(at, polylines)| Junction {
            at: q[at as usize],
            polylines,
        })
        .collect();
    orient_loops(&mut out.polylines);
    out
}

/// Turns each closed curve counter-clockwise, or clockwise where it lies inside an odd
/// number of the others (a hole), as the level set's loops turn (the inside on the
/// left): a tree's cycles run whichever way its walk found them. Loops do not cross
/// (no two edges do), so one vertex tells whether a loop lies inside another.
fn orient_loops(polylines: &mut [Polyline]) {
    let depth: Vec<usize> = polylines
        .iter()
        .enumerate()
        .map(|(i, c)| match (c.closed, c.points.first()) {
            (true, Some(&p)) => polylines
                .iter()
                .enumerate()
                .filter(|&(j, o)| j != i && o.encloses(p))
                .count(),
            _ => 0,
        })
        .collect();
    for (c, d) in polylines.iter_mut().zip(depth) {
        if c.closed && (c.signed_area() > 0.0) != (d % 2 == 0) {
            c.points.reverse();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The graph of `field`'s samples with noise `sigma`, and the accuracy bound of a
    /// unit box's default mesh (`3 sigma + 2 hmin`, `hmin` about a thousandth of the box).
    fn graph(field: &DistanceField, sigma: f64) -> Graphed {
        graph_curves(field, sigma, 3.0 * sigma + 0.002)
    }

    /// That `g` is one closed loop, every vertex within `bound` of the circle of radius
    /// 0.3 round (0.5, 0.5) that [`noisy_circle`] samples.
    fn one_loop_on_the_circle(g: &Graphed, bound: f64, case: usize) {
        assert_eq!(g.polylines.len(), 1, "case {case}");
        assert!(g.polylines[0].closed, "case {case}");
        for &p in &g.polylines[0].points {
            let off = (dist(p, [0.5, 0.5]) - 0.3).abs();
            assert!(off <= bound, "case {case}: {p:?} {off} > {bound}");
        }
    }

    /// A deterministic pseudo-random sequence in [0, 1).
    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    fn gauss(seed: &mut u64) -> f64 {
        let (u, v) = (lcg(seed).max(1e-300), lcg(seed));
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// Samples of a noisy Archimedean spiral from radius 0.12 to 0.4 over three turns
    /// round (0.5, 0.5), and the distance from a point to it.
    fn spiral(n: usize, sigma: f64, seed: &mut u64) -> (Vec<Point>, impl Fn(Point) -> f64) {
        let turns = 3.0;
        let at = |t: f64| {
            let th = std::f64::consts::TAU * turns * t;
            let rad = 0.12 + 0.28 * t;
            [0.5 + rad * th.cos(), 0.5 + rad * th.sin()]
        };
        let dense: Vec<Point> = (0..=20_000).map(|i| at(i as f64 / 20_000.0)).collect();
        let pts = (0..n)
            .map(|_| {
                let p = at(lcg(seed));
                [p[0] + sigma * gauss(seed), p[1] + sigma * gauss(seed)]
            })
            .collect();
        let d = move |p: Point| {
            dense
                .iter()
                .map(|&c| dist(c, p))
                .fold(f64::INFINITY, f64::min)
        };
        (pts, d)
    }

    /// `n` samples uniform on the circle of radius 0.3 about (0.5, 0.5), with Gaussian
    /// noise `sigma` per coordinate.
    fn noisy_circle(n: usize, sigma: f64, seed: &mut u64) -> Vec<Point> {
        (0..n)
            .map(|_| {
                let a = std::f64::consts::TAU * lcg(seed);
                [
                    0.5 + 0.3 * a.cos() + sigma * gauss(seed),
                    0.5 + 0.3 * a.sin() + sigma * gauss(seed),
                ]
            })
            .collect()
    }

    /// A noisy spiral whose turns lie 0.093 apart at sigma = 0.008 (its band's edges
    /// 0.06 apart) is one open curve, every vertex within the accuracy bound of the
    /// truth (3 sigma plus the sampling's spacing) and the truth within it of a
    /// vertex but near the ends (a free end stops short by up to a window).
    #[test]
    fn a_noisy_spiral_is_one_curve_near_its_truth() {
        let sigma = 0.008;
        let mut seed = 7;
        let (pts, truth) = spiral(3000, sigma, &mut seed);
        let field = DistanceField::new(&pts).unwrap();
        let g = graph(&field, sigma);
        assert_eq!(g.polylines.len(), 1, "{:?}", g.polylines.len());
        assert!(!g.polylines[0].closed);
        let worst = g.polylines[0]
            .points
            .iter()
            .map(|&p| truth(p))
            .fold(0.0, f64::max);
        assert!(worst <= 3.0 * sigma + 0.005, "{worst}");
    }

    /// Samples exactly on a line (no noise: their fits' residuals are rounding) are one
    /// curve along it, none an outlier of its own window's fit.
    #[test]
    fn clean_samples_on_a_line_are_one_curve() {
        let pts: Vec<Point> = (0..300)
            .map(|i| {
                let t = i as f64 / 299.0;
                [0.1 + 0.8 * t, 0.3 + 0.4 * t]
            })
            .collect();
        let field = DistanceField::new(&pts).unwrap();
        let g = graph(&field, 0.0);
        assert_eq!(g.polylines.len(), 1);
        assert!(
            g.polylines[0].points.len() >= 290,
            "{}",
            g.polylines[0].points.len()
        );
    }

    /// Uniformly scattered points fill an area: no window sees a curve, nothing is drawn.
    #[test]
    fn scattered_points_draw_nothing() {
        let mut seed = 3;
        let pts: Vec<Point> = (0..2000)
            .map(|_| [lcg(&mut seed), lcg(&mut seed)])
            .collect();
        let field = DistanceField::new(&pts).unwrap();
        let g = graph(&field, 0.0);
        let len: f64 = g
            .polylines
            .iter()
            .flat_map(|pl| pl.points.windows(2).map(|w| dist(w[0], w[1])))
            .sum();
        assert!(len < 0.1, "{len} of curve through scattered points");
    }

    /// A noisy circle sampled far more densely than its noise needs is thinned to a
    /// typical ten-sample radius of half the noise: every local density falls by the
    /// same factor, so every radius grows by its square root (within 15%: the median of
    /// thousands of ten-sample radii, each varying by about a sixth). The kept count is
    /// binomial (within five deviations). Data sparser than that, or without noise, are
    /// not thinned.
    #[test]
    fn dense_noisy_samples_are_thinned_to_half_the_noise() {
        let median = |f: &DistanceField| typical(&ten_sample_radii(f));
        let sigma = 0.01;
        let field = DistanceField::new(&noisy_circle(60_000, sigma, &mut 7)).unwrap();
        let n = field.points().len() as f64;
        let before = median(&field);
        let kept =
            thinned(&field, &ten_sample_radii(&field), sigma).expect("dense samples are thinned");
        let p = (before / (0.5 * sigma)).powi(2);
        let m = kept.points().len() as f64;
        assert!(
            (m - p * n).abs() <= 5.0 * (n * p * (1.0 - p)).sqrt(),
            "{m} kept of {n}, expected {}",
            p * n
        );
        let after = median(&kept);
        assert!(
            (after / (0.5 * sigma) - 1.0).abs() < 0.15,
            "typical ten-sample radius {after} against {}",
            0.5 * sigma
        );
        let sparse = DistanceField::new(&noisy_circle(500, sigma, &mut 7)).unwrap();
        assert!(thinned(&sparse, &ten_sample_radii(&sparse), sigma).is_none());
        assert!(thinned(&field, &ten_sample_radii(&field), 0.0).is_none());
    }

    /// A noisy circle closes: its tree misses one edge, and the ends face each other.
    /// Outliers are drawn into no curve: a noisy circle with 5% of its samples replaced
    /// by points uniform over the unit square has every vertex within the accuracy
    /// bound of the circle (3 sigma and a sampling spacing), on 64 random samplings.
    /// Without the density test, 4 of them keep outliers beside the band whose windows
    /// held only the band's tail.
    #[test]
    fn outliers_beside_a_noisy_loop_are_in_no_curve() {
        let sigma = 0.008;
        for case in 0..64u64 {
            let mut seed = 1000 + case;
            let mut pts = noisy_circle(1900, sigma, &mut seed);
            pts.extend((0..100).map(|_| [lcg(&mut seed), lcg(&mut seed)]));
            let field = DistanceField::new(&pts).unwrap();
            let g = graph(&field, sigma);
            let worst = g
                .polylines
                .iter()
                .flat_map(|pl| &pl.points)
                .map(|&p| (dist(p, [0.5, 0.5]) - 0.3).abs())
                .fold(0.0, f64::max);
            assert!(worst <= 3.0 * sigma + 0.005, "case {case}: {worst}");
        }
    }

    /// A few samples near a curve whose windows see a curve of their own (outliers near
    /// each other, or the tail of a band) are below the graph's resolution when their
    /// chain is shorter than two of its windows: they run into the curve as no T (a
    /// whisker into empty space), and are drawn as no piece of their own. Here a dash
    /// of twelve clean samples 3 mm apart, pointing at a clean line of samples 2 mm
    /// apart from 2 cm away: every vertex drawn lies on the line.
    #[test]
    fn a_dash_below_the_resolution_is_no_whisker() {
        let mut pts: Vec<Point> = (0..=400).map(|i| [0.1 + 0.002 * i as f64, 0.5]).collect();
        pts.extend((0..12).map(|i| [0.5, 0.52 + 0.003 * i as f64]));
        let field = DistanceField::new(&pts).unwrap();
        let g = graph(&field, 0.0);
        let off: Vec<Point> = g
            .polylines
            .iter()
            .flat_map(|pl| pl.points.iter().copied())
            .filter(|p| (p[1] - 0.5).abs() > 1e-9)
            .collect();
        assert!(off.is_empty(), "{off:?}");
        assert_eq!(g.polylines.len(), 1, "{:?}", g.polylines.len());
    }

    /// An annulus's two loops: the outer counter-clockwise, the hole clockwise, on
    /// every sampling (a tree's walk finds its cycles either way round).
    #[test]
    fn an_outline_turns_counter_clockwise_and_its_hole_clockwise() {
        let mut seed = 7;
        for case in 0..16 {
            let mut pts = noisy_circle(600, 0.003, &mut seed);
            let inner: Vec<Point> = noisy_circle(300, 0.003, &mut seed)
                .into_iter()
                .map(|p| add(scale(sub(p, [0.5, 0.5]), 0.5), [0.5, 0.5]))
                .collect();
            pts.extend(inner);
            let g = graph(&DistanceField::new(&pts).unwrap(), 0.003);
            let loops: Vec<&Polyline> = g.polylines.iter().filter(|c| c.closed).collect();
            assert_eq!(loops.len(), 2, "case {case}: {:?}", g.polylines.len());
            let (outer, hole) = if loops[0].signed_area().abs() > loops[1].signed_area().abs() {
                (loops[0], loops[1])
            } else {
                (loops[1], loops[0])
            };
            assert!(outer.signed_area() > 0.0, "case {case}");
            assert!(hole.signed_area() < 0.0, "case {case}");
        }
    }

    /// A loop sampled so sparsely that ten samples span more than the noise
    /// measurement's largest window (150 samples round a circle of radius 0.3: ten span
    /// about 0.06, the largest window a sixteenth of 0.6) is still one loop near its
    /// truth: the windows may grow to hold ten samples.
    #[test]
    fn a_sparsely_sampled_noisy_loop_is_one_loop() {
        let mut seed = 11;
        let sigma = 0.004;
        for case in 0..16 {
            let pts = noisy_circle(150, sigma, &mut seed);
            let field = DistanceField::new(&pts).unwrap();
            assert!(
                window_cap(&field, &ten_sample_radii(&field)) > largest_window(&field),
                "case {case}: not sparse"
            );
            let g = graph(&field, sigma);
            // Within the accuracy bound of the truth: three deviations and a spacing.
            one_loop_on_the_circle(&g, 3.0 * sigma + std::f64::consts::TAU * 0.3 / 150.0, case);
        }
    }

    /// A noisy loop sampled ten times more sparsely on one half than on the other (1,200
    /// and 120 samples round a circle of radius 0.3, sigma = 0.002) is one closed loop
    /// near its truth: the sparse half's ten-sample radius (about 0.04) is past every
    /// cap (three times a typical sample's, about 0.012, and a sixteenth of the extent),
    /// and its samples qualify at their own ten, which lie on their fit. Capped, they
    /// were lost and the loop came out as an open curve round the dense half.
    #[test]
    fn a_loop_sampled_ten_times_more_sparsely_on_one_side_closes() {
        let mut seed = 5;
        let sigma = 0.002;
        for case in 0..8 {
            let pts: Vec<Point> = (0..1320)
                .map(|i| {
                    let t = lcg(&mut seed);
                    let a = std::f64::consts::PI * if i < 1200 { t } else { 1.0 + t };
                    [
                        0.5 + 0.3 * a.cos() + sigma * gauss(&mut seed),
                        0.5 + 0.3 * a.sin() + sigma * gauss(&mut seed),
                    ]
                })
                .collect();
            let g = graph(&DistanceField::new(&pts).unwrap(), sigma);
            // Three deviations and the sparse half's spacing, about 0.008.
            one_loop_on_the_circle(&g, 3.0 * sigma + std::f64::consts::PI * 0.3 / 120.0, case);
        }
    }

    #[test]
    fn a_noisy_circle_is_one_loop() {
        let mut seed = 11;
        let pts = noisy_circle(1500, 0.005, &mut seed);
        let field = DistanceField::new(&pts).unwrap();
        let g = graph(&field, 0.005);
        let shape: Vec<(bool, usize, Point, Point)> = g
            .polylines
            .iter()
            .map(|pl| {
                (
                    pl.closed,
                    pl.points.len(),
                    pl.points[0],
                    *pl.points.last().unwrap(),
                )
            })
            .collect();
        assert_eq!(g.polylines.len(), 1, "{shape:?} {:?}", g.junctions);
        assert!(g.polylines[0].closed);
        for &p in &g.polylines[0].points {
            let d = (dist(p, [0.5, 0.5]) - 0.3).abs();
            assert!(d <= 3.0 * 0.005, "{d}");
        }
    }

    /// The segments of `g`'s curves, and each vertex's count of segments.
    fn segments(g: &Graphed) -> Vec<(Point, Point)> {
        g.polylines
            .iter()
            .flat_map(|pl| {
                let n = pl.points.len();
                let m = if pl.closed { n } else { n - 1 };
                (0..m).map(move |i| (pl.points[i], pl.points[(i + 1) % n]))
            })
            .collect()
    }

    /// A graph built by hand, renumbered into the order its field keeps (by x, then y),
    /// as [`graph_curves`]' vertices are: `continue_ends` finds vertices through the
    /// field's indices. Returns each old vertex's new index too.
    #[allow(clippy::type_complexity)]
    fn in_field_order(
        q: &[Point],
        r: &[f64],
        tangents: &[Point],
        adj: &[Vec<u32>],
    ) -> (Vec<Point>, Vec<f64>, Vec<Point>, Vec<Vec<u32>>, Vec<u32>) {
        let mut order: Vec<u32> = (0..q.len() as u32).collect();
        order.sort_by(|&a, &b| {
            let (a, b) = (q[a as usize], q[b as usize]);
            a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1]))
        });
        let mut at = vec![0u32; q.len()];
        for (k, &v) in order.iter().enumerate() {
            at[v as usize] = k as u32;
        }
        (
            order.iter().map(|&v| q[v as usize]).collect(),
            order.iter().map(|&v| r[v as usize]).collect(),
            order.iter().map(|&v| tangents[v as usize]).collect(),
            order
                .iter()
                .map(|&v| adj[v as usize].iter().map(|&w| at[w as usize]).collect())
                .collect(),
            at,
        )
    }

    /// A fork's branch pointing at another curve 0.085 ahead (windows 0.05): shorter
    /// than two windows (0.057, the tip an acute corner leaves) it does not run into
    /// that curve; at 0.113 it is a stroke and does.
    #[test]
    fn a_branch_below_the_resolution_runs_into_no_curve() {
        for (steps, joins) in [(4, false), (8, true)] {
            let mut q: Vec<Point> = Vec::new();
            let mut tangents = Vec::new();
            let mut adj: Vec<Vec<u32>> = Vec::new();
            let mut piece = |from: Point, step: Point, n: usize, link: Option<u32>| {
                let first = q.len() as u32;
                for i in 0..n {
                    q.push(add(from, scale(step, i as f64)));
                    tangents.push(scale(step, 1.0 / dist(step, [0.0, 0.0])));
                    adj.push(Vec::new());
                }
                for k in first..first + n as u32 - 1 {
                    adj[k as usize].push(k + 1);
                    adj[k as usize + 1].push(k);
                }
                if let Some(v) = link {
                    adj[v as usize].push(first);
                    adj[first as usize].push(v);
                }
                first
            };
            // A line with a fork at (0.3, 0), the branch up and to the right from it,
            // and a curve along y = 0.1 ahead of the branch's end.
            piece([0.0, 0.0], [0.01, 0.0], 31, None);
            piece([0.31, 0.0], [0.01, 0.0], 30, Some(30));
            let b = piece([0.31, 0.01], [0.01, 0.01], steps, Some(30));
            piece([0.2, 0.1], [0.01, 0.0], 41, None);
            let r = vec![0.05; q.len()];
            let (q, r, tangents, mut adj, at) = in_field_order(&q, &r, &tangents, &adj);
            let end = at[(b + steps as u32 - 1) as usize] as usize;
            let q_field = DistanceField::new(&q).unwrap();
            assert_eq!(q_field.points(), &q[..]);
            continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Facing);
            continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Ahead);
            assert_eq!(adj[end].len() == 2, joins, "{steps}: {:?}", adj[end]);
        }
    }

    /// Outlines with concave corners (a notch cut into a box, its sides meeting at 90
    /// and at 53 degrees), twelve random samplings each with noise: round a corner both walls' trees stop short of
    /// it, and the two ends meet there as one curve turning, not one wall's end running
    /// into the other's side (a fork no closed outline has). One closed loop, no
    /// junction.
    #[test]
    fn an_outline_turns_at_its_concave_corners() {
        use rand::{Rng, SeedableRng};
        let notch = |depth: f64| -> Vec<Point> {
            vec![
                [0.1, 0.1],
                [0.9, 0.1],
                [0.9, 0.9],
                [0.6, 0.9],
                [0.5, 0.9 - depth],
                [0.4, 0.9],
                [0.1, 0.9],
            ]
        };
        for (depth, seed) in [0.1, 0.2]
            .into_iter()
            .flat_map(|d| (1..=12u64).map(move |k| (d, k)))
        {
            let corners = notch(depth);
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let len: f64 = (0..corners.len())
                .map(|i| dist(corners[i], corners[(i + 1) % corners.len()]))
                .sum();
            let pts: Vec<Point> = (0..3000)
                .map(|_| {
                    let mut s = rng.random::<f64>() * len;
                    let mut i = 0;
                    loop {
                        let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
                        let l = dist(a, b);
                        if s <= l {
                            let p = add(a, scale(sub(b, a), s / l));
                            break [
                                p[0] + 0.002 * (rng.random::<f64>() - 0.5),
                                p[1] + 0.002 * (rng.random::<f64>() - 0.5),
                            ];
                        }
                        s -= l;
                        i += 1;
                    }
                })
                .collect();
            let g = graph(&DistanceField::new(&pts).unwrap(), 0.0);
            let shape: Vec<(usize, bool)> = g
                .polylines
                .iter()
                .map(|p| (p.points.len(), p.closed))
                .collect();
            assert!(
                g.junctions.is_empty() && g.polylines.len() == 1 && g.polylines[0].closed,
                "depth {depth} seed {seed}: {shape:?}, {} junctions",
                g.junctions.len()
            );
        }
    }

    /// Two strokes with gaps that cross: a long gap (0.6, its ends' windows 0.31) and,
    /// through its middle, a short one (0.2, windows 0.11). The long gap closes first;
    /// the short one would cross that join, whose ends lie farther from the crossing
    /// than the short gap's half length plus the tree's longest edge (0.01). The
    /// crossing check's reach must have grown with the first join to see it.
    #[test]
    fn a_join_is_not_crossed_by_a_shorter_one() {
        let mut q: Vec<Point> = Vec::new();
        let mut r = Vec::new();
        let mut tangents = Vec::new();
        let mut adj: Vec<Vec<u32>> = Vec::new();
        let mut piece = |from: Point, step: Point, n: usize, window: f64| {
            let first = q.len() as u32;
            for i in 0..n {
                q.push(add(from, scale(step, i as f64)));
                r.push(window);
                tangents.push(scale(step, 1.0 / dist(step, [0.0, 0.0])));
                adj.push(Vec::new());
            }
            for k in first..first + n as u32 - 1 {
                adj[k as usize].push(k + 1);
                adj[k as usize + 1].push(k);
            }
        };
        // The long gap, from (0.1, 0) to (0.7, 0), first: its ends are the first
        // visited.
        piece([0.1, 0.0], [-0.01, 0.0], 31, 0.31);
        piece([0.7, 0.0], [0.01, 0.0], 31, 0.31);
        // The short gap, from (0.4, -0.1) to (0.4, 0.1).
        piece([0.4, -0.1], [0.0, -0.01], 26, 0.11);
        piece([0.4, 0.1], [0.0, 0.01], 26, 0.11);
        let (q, r, tangents, mut adj, at) = in_field_order(&q, &r, &tangents, &adj);
        let [e0, e31, e62, e88] = [0, 31, 62, 88].map(|v| at[v] as usize);
        let q_field = DistanceField::new(&q).unwrap();
        assert_eq!(q_field.points(), &q[..]);
        continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Facing);
        continue_ends(&q, &r, &tangents, &q_field, &mut adj, Pass::Ahead);
        assert!(adj[e0].contains(&(e31 as u32)), "the long gap closes");
        assert_eq!(
            adj[e62].len(),
            1,
            "the short gap's ends stay free: {:?}",
            adj[e62]
        );
        assert_eq!(adj[e88].len(), 1, "{:?}", adj[e88]);
        let edges: Vec<(Point, Point)> = (0..q.len())
            .flat_map(|a| adj[a].iter().map(move |&b| (a, b as usize)))
            .filter(|&(a, b)| a < b)
            .map(|(a, b)| (q[a], q[b]))
            .collect();
        for (i, &(a, b)) in edges.iter().enumerate() {
            for &(c, d) in &edges[i + 1..] {
                let shared = [c, d].iter().any(|&x| x == a || x == b);
                assert!(
                    shared || crossing(a, b, c, d).is_none(),
                    "{a:?}-{b:?} crosses {c:?}-{d:?}"
                );
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
        /// Whatever the drawing (random strokes, noise up to 1% of the box, up to 10%
        /// outliers), the stage's own output meets its contract, with no cut after
        /// it: no two segments cross but at a shared vertex, no vertex has more than
        /// six segments, every vertex lies within the largest window of a sample,
        /// and junctions index the curves.
        #[test]
        fn the_graph_meets_its_contract(
            strokes in proptest::collection::vec(
                proptest::collection::vec((0.1f64..0.9, 0.1f64..0.9), 2..5), 1..5),
            sigma in 0.0f64..0.01,
            outliers in 0.0f64..0.1,
            seed in 0u64..1000,
        ) {
            let mut seed = seed;
            let mut pts = Vec::new();
            for s in &strokes {
                for w in s.windows(2) {
                    let (a, b) = ([w[0].0, w[0].1], [w[1].0, w[1].1]);
                    let k = (dist(a, b) * 600.0) as usize + 2;
                    for _ in 0..k {
                        let t = lcg(&mut seed);
                        let p = add(a, scale(sub(b, a), t));
                        pts.push([p[0] + sigma * gauss(&mut seed), p[1] + sigma * gauss(&mut seed)]);
                    }
                }
            }
            let n_out = (outliers * pts.len() as f64) as usize;
            for _ in 0..n_out {
                pts.push([lcg(&mut seed), lcg(&mut seed)]);
            }
            let field = DistanceField::new(&pts).unwrap();
            let g = graph(&field, sigma);
            let segs = segments(&g);
            for (i, &(a, b)) in segs.iter().enumerate() {
                for &(c, d) in &segs[i + 1..] {
                    let shared = [c, d].iter().any(|&x| x == a || x == b);
                    proptest::prop_assert!(
                        shared || crossing(a, b, c, d).is_none(),
                        "{a:?}-{b:?} crosses {c:?}-{d:?}"
                    );
                }
            }
            let mut degree = std::collections::HashMap::new();
            for &(a, b) in &segs {
                for p in [a, b] {
                    *degree.entry((p[0].to_bits(), p[1].to_bits())).or_insert(0) += 1;
                }
            }
            proptest::prop_assert!(degree.values().all(|&d| d <= 6), "{:?}", degree.values().max());
            let r_max = largest_window(&field);
            for pl in &g.polylines {
                for &p in &pl.points {
                    proptest::prop_assert!(field.distance(p) <= r_max);
                }
            }
            for j in &g.junctions {
                proptest::prop_assert!(j.polylines.iter().all(|&k| k < g.polylines.len()));
            }
        }
    }

    /// Two clean strokes crossing at 90, 60 and 40 degrees, each sampled evenly and
    /// shifted along itself by sixths of its spacing: one junction where four curves
    /// meet. Without the rules for crossings the tree links the samples as two T's a
    /// few samples apart, or the arms' ends as two corners (two L's).
    #[test]
    fn crossing_strokes_meet_at_one_junction() {
        for angle in [90f64, 40.0] {
            for shift in 0..6 {
                let (s, c) = angle.to_radians().sin_cos();
                let t = |i: usize| (i as f64 + shift as f64 / 6.0) / 1000.0 - 0.5;
                let pts: Vec<Point> = (0..1000)
                    .map(|i| [0.5 + t(i), 0.5])
                    .chain((0..1000).map(|i| [0.5 + t(i) * c, 0.5 + t(i) * s]))
                    .collect();
                let g = graph(&DistanceField::new(&pts).unwrap(), 0.0);
                let degrees: Vec<usize> = g.junctions.iter().map(|j| j.polylines.len()).collect();
                let ends: Vec<_> = g
                    .polylines
                    .iter()
                    .map(|p| {
                        (
                            p.points.len(),
                            p.points[0],
                            *p.points.last().unwrap(),
                            p.closed,
                        )
                    })
                    .collect();
                assert_eq!(degrees, [4], "{angle} degrees, shift {shift}: {ends:?}");
                assert_eq!(g.polylines.len(), 4, "{angle} degrees, shift {shift}");
                let at = g.junctions[0].at;
                assert!(dist(at, [0.5, 0.5]) < 0.005, "{angle} degrees: {at:?}");
            }
        }
    }
}

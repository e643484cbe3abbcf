//! Initial level sets: signed distance functions (negative inside) to a starting curve
//! that encloses the data, evaluated at the mesh vertices.

use rayon::prelude::*;

use crate::disjoint::root;
use crate::distance::DistanceField;
use crate::fem::P1Space;
use crate::geom::{dist, sub, BBox, Point};
use crate::mesh::{Mesh, VertexTag};
use crate::redistance::Redistancer;
use crate::scan::FreeSpace;

/// Where the evolution starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Init {
    /// The paper's start (section 4.1): a circle centred on the data's bounding box that
    /// encloses every point with a margin.
    Circle,
    /// A rounded rectangle around the data's bounding box with the same margin. It hugs
    /// elongated data much more closely than a circle, so the curve has less far to go.
    Box,
    /// The outer boundary of the tube `{d < delta}` around the data (docs/method.md,
    /// starting curve): the regions outside the tube are labelled inside or outside by how many tube
    /// crossings separate them from the domain boundary, so holes and separate components
    /// start out right, and the curve starts `delta` from the data everywhere, concavities
    /// included.
    Tube,
    /// The middle of that tube (see `medial`): the same labelling, the curve starting
    /// in the middle of the noise band instead of `delta` outside it.
    #[default]
    Medial,
}

impl std::str::FromStr for Init {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "circle" => Ok(Init::Circle),
            "box" => Ok(Init::Box),
            "tube" => Ok(Init::Tube),
            "medial" => Ok(Init::Medial),
            _ => Err(format!(
                "unknown init {s:?}: expected \"medial\", \"tube\", \"box\" or \"circle\""
            )),
        }
    }
}

/// The signed distance at each of `coords` to the starting curve `init` around
/// `points`, which stays `margin` away from every point.
pub fn enclosing(init: Init, points: &[Point], margin: f64, coords: &[Point]) -> Vec<f64> {
    let Some(bbox) = BBox::of(points) else {
        return vec![f64::INFINITY; coords.len()];
    };
    match init {
        Init::Circle => {
            let c = bbox.center();
            let r = points.iter().map(|&p| dist(p, c)).fold(0.0, f64::max) + margin;
            circle(c, r, coords)
        }
        Init::Tube | Init::Medial => {
            unreachable!("the tube starts need the mesh: use `tube` or `medial`")
        }
        Init::Box => {
            let size = bbox.size();
            let half = [0.5 * size[0] + margin, 0.5 * size[1] + margin];
            // Corners rounded with radius `margin`: every point of the data's box is then
            // at least `margin` inside.
            rounded_box(bbox.center(), half, margin, coords)
        }
    }
}

/// A cold start: the level set and the start it came from.
#[derive(Clone, Debug)]
pub struct ColdStart {
    /// The signed distance to the starting curve at each vertex (negative inside).
    pub u: Vec<f64>,
    /// The start used: the one asked for, or [`Init::Box`] when a tube start found
    /// nothing enclosed.
    pub init: Init,
}

/// The oriented start offered to [`cold_start`] (see [`crate::levelset::orient`]).
#[derive(Clone, Copy, Debug)]
pub struct Oriented<'a> {
    /// The offsets from the oriented samples' tangent lines at each vertex.
    pub offsets: &'a [f64],
    /// Whether the data's noise is small beside the tube (under an eighth of its
    /// radius), so that a start that misses the samples is wrong.
    pub clean: bool,
}

/// The level set `init` asks for on `mesh` (`dist`: the distance to the data `points`
/// at each vertex), renormalized: the tube starts with the tube of radius
/// `tube_radius`, or twice that when it encloses nothing, opened along `corridor` (see
/// [`corridors`], computed up to `4 tube_radius`; empty for none), falling back to the
/// box when neither tube encloses anything; the enclosing starts `margin` from the
/// data. The tube starts give way to `oriented` where the two disagree.
#[allow(clippy::too_many_arguments)]
pub fn cold_start(
    init: Init,
    mesh: &Mesh,
    space: &P1Space,
    dist: &[f64],
    points: &[Point],
    tube_radius: f64,
    corridor: Option<&Corridors<'_>>,
    oriented: Option<Oriented<'_>>,
    margin: f64,
    fm: &mut Redistancer,
) -> ColdStart {
    // A tube that leaks between sparse samples encloses nothing: one twice as wide closes
    // gaps twice as long, and the corridors keep the inlets it would close open.
    let tube_start = |fm: &mut Redistancer, delta: f64| match init {
        Init::Medial => medial(mesh, space, dist, delta, corridor, fm),
        _ => tube(mesh, |v| space.ring(v), dist, delta, corridor),
    };
    let start = match init {
        Init::Medial | Init::Tube => {
            tube_start(fm, tube_radius).or_else(|| tube_start(fm, 2.0 * tube_radius))
        }
        Init::Box | Init::Circle => {
            return ColdStart {
                u: enclosing(init, points, margin, &mesh.coords),
                init,
            }
        }
    };
    let start = start.map(|mut u| {
        fm.run(mesh, space, &mut u, f64::INFINITY);
        u
    });
    // The oriented samples' offsets (see [`crate::levelset::orient`]) know which side
    // of each wall is out however close the next wall is; the tube's parity does not
    // once its walls merge, which joins regions the walls keep apart, cuts a corridor
    // into pockets or fills one from its end. Where the two starts' regions differ, or
    // their sides do at more than 1% of the vertices away from the data, the offsets
    // start.
    if let Some(Oriented { offsets, clean }) = oriented.filter(|o| o.offsets.len() == dist.len()) {
        let differ = |u: &[f64]| {
            let (mut away, mut wrong) = (0usize, 0usize);
            for v in (0..dist.len()).filter(|&v| dist[v] > tube_radius) {
                away += 1;
                wrong += usize::from((u[v] < 0.0) != (offsets[v] < 0.0));
            }
            // And on clean data where the offsets run through the samples and the tube's
            // middle does not (samples sparser than the tube is wide, or walls closer
            // than it): the vertices next to a sample lie next to the offsets' curve,
            // while the merged tube's middle passes such a sample by half the gap. A
            // count, not a mean: the middle may be off only along one turn of a spiral.
            // In a noisy band neither start runs through the samples.
            let passed_by = |u: &[f64]| {
                (0..dist.len())
                    .filter(|&v| dist[v] < 0.25 * tube_radius)
                    .filter(|&v| u[v].abs() > dist[v] + 0.25 * tube_radius)
                    .count()
            };
            wrong * 100 > away
                || regions(space, u) != regions(space, offsets)
                || (clean && {
                    let near = (0..dist.len())
                        .filter(|&v| dist[v] < 0.25 * tube_radius)
                        .count();
                    let missed = passed_by(u);
                    missed * 100 > near && passed_by(offsets) * 2 < missed
                })
        };
        if start.as_deref().is_none_or(differ) {
            tracing::debug!("the tube's start and the oriented one disagree: oriented start");
            let mut u = offsets.to_vec();
            fm.run(mesh, space, &mut u, f64::INFINITY);
            return ColdStart { u, init };
        }
    }
    match start {
        Some(u) => ColdStart { u, init },
        None => {
            tracing::debug!(tube_radius, "the tube encloses nothing: box start");
            ColdStart {
                u: enclosing(Init::Box, points, margin, &mesh.coords),
                init: Init::Box,
            }
        }
    }
}

/// Regions smaller than this (in vertices) are specks of noise, not topology.
const MIN_REGION: usize = 16;

/// The numbers of connected regions (of at least [`MIN_REGION`] vertices) where `u` is
/// negative and where it is not.
fn regions(space: &P1Space, u: &[f64]) -> (usize, usize) {
    let n = u.len();
    let mut seen = vec![false; n];
    let mut stack = Vec::new();
    let (mut inside, mut outside) = (0, 0);
    for seed in 0..n {
        if seen[seed] {
            continue;
        }
        let side = u[seed] < 0.0;
        seen[seed] = true;
        stack.push(seed);
        let mut size = 0;
        while let Some(v) = stack.pop() {
            size += 1;
            for &w in space.ring(v) {
                let w = w as usize;
                if !seen[w] && (u[w] < 0.0) == side {
                    seen[w] = true;
                    stack.push(w);
                }
            }
        }
        if size >= MIN_REGION {
            if side {
                inside += 1;
            } else {
                outside += 1;
            }
        }
    }
    (inside, outside)
}

/// The padding (a fraction of the bounding box's diagonal) the mesh needs for the
/// paper's circle start, `margin` from every point of `points`, to fit in it.
pub fn circle_padding(points: &[Point], margin: f64) -> f64 {
    let Some(bbox) = BBox::of(points) else {
        return 0.0;
    };
    let diag = bbox.diag();
    if diag <= 0.0 {
        return 0.0;
    }
    let c = bbox.center();
    let r = points.iter().map(|&p| dist(p, c)).fold(0.0, f64::max) + margin;
    let half = bbox.size()[0].min(bbox.size()[1]) / 2.0;
    (r - half) / diag + 0.05
}

/// The empty strip a corridor vertex lies in (see [`corridors`]), in the vertex's
/// frame: `across` is the unit direction to the nearest sample, and no sample lies
/// within the window at an offset `b` along it with `-far < b < near`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strip {
    /// Unit direction to the near wall.
    pub across: Point,
    /// Distance to the near wall (the vertex's distance to the data).
    pub near: f64,
    /// Distance to the far wall, the other way along `across`.
    pub far: f64,
}

impl Strip {
    /// Whether `w`, seen from the strip's vertex at `v`, lies inside the strip (with a
    /// tenth of its width to spare on each side): a mesh edge from `v` to `w` then runs
    /// along the corridor instead of across one of its walls.
    fn holds(&self, v: Point, w: Point) -> bool {
        let e = sub(w, v);
        let b = e[0] * self.across[0] + e[1] * self.across[1];
        b < 0.9 * self.near && b > -0.9 * self.far
    }
}

/// What [`corridors`] found: a strip at each corridor vertex, and the data, to tell
/// whether a segment between two vertices crosses a wall.
pub struct Corridors<'a> {
    /// The strip of each mesh vertex that lies in a corridor.
    pub strips: Vec<Option<Strip>>,
    field: &'a DistanceField,
}

impl Corridors<'_> {
    /// Whether the segment from `p` to `q` keeps at least `clearance` from every
    /// sample (checked every quarter of it).
    fn clear(&self, p: Point, q: Point, clearance: f64) -> bool {
        let steps = (dist(p, q) / (0.25 * clearance)).ceil().max(1.0) as usize;
        (0..=steps).all(|i| {
            let f = i as f64 / steps as f64;
            let x = [p[0] + (q[0] - p[0]) * f, p[1] + (q[1] - p[1]) * f];
            self.field.distance(x) >= clearance
        })
    }
}

/// The strip of vertex `v`, if it lies in a corridor.
fn strip_at(corridor: Option<&Corridors<'_>>, v: usize) -> Option<Strip> {
    corridor.and_then(|c| c.strips.get(v).copied().flatten())
}

/// The vertices lying in a corridor between two walls of samples: the samples within
/// `3 d` of the vertex (`d` its distance to the data, between `lo` and `hi`) fall into
/// two sheets, one on either side of it, each stretching at least `2 d` along the
/// corridor (counting the samples within `d` of each sheet's nearest, not a wall
/// beyond it), with none closer than `d / 2` to the line through the vertex along it.
/// The direction across is the one to the nearest sample (`nearest`), which is the near
/// wall's normal. Such a vertex is free space even where the tube around the data
/// covers it: the gap between two walls narrower than the tube stays open.
///
/// A hole between two samples of one wall is no corridor: the samples on either side of
/// it lie along the direction across, not along the corridor; nor is a hole among the
/// samples of a noisy band, where the band's samples fill the line through the vertex.
pub fn corridors<'a>(
    field: &'a DistanceField,
    coords: &[Point],
    dist: &[f64],
    nearest: &[u32],
    lo: f64,
    hi: f64,
) -> Corridors<'a> {
    // Each wall needs this many samples in the window to count as a sheet.
    const MIN_SAMPLES: usize = 3;
    let pts = field.points();
    let strips = coords
        .par_iter()
        .zip(dist.par_iter().zip(nearest.par_iter()))
        .map_init(Vec::new, |buf, (&p, (&d, &j))| {
            if !(d >= lo && d < hi) || d <= 0.0 {
                return None;
            }
            let q = pts[j as usize];
            let across = [(q[0] - p[0]) / d, (q[1] - p[1]) / d];
            field.within(p, 3.0 * d, buf);
            let local = |i: u32| {
                let w = sub(pts[i as usize], p);
                let b = w[0] * across[0] + w[1] * across[1];
                let a = w[1] * across[0] - w[0] * across[1];
                (b, a)
            };
            // The nearest offset on each side; none in the strip's middle.
            let mut nearest_b = [f64::INFINITY; 2];
            for &i in buf.iter() {
                let (b, _) = local(i);
                if b.abs() < 0.5 * d {
                    return None;
                }
                let side = &mut nearest_b[usize::from(b < 0.0)];
                *side = side.min(b.abs());
            }
            // Each wall: the samples within d of its nearest offset (the wall itself, not
            // a wall beyond it), their count and their extent along the corridor.
            let mut walls = [(0usize, f64::INFINITY, f64::NEG_INFINITY); 2];
            for &i in buf.iter() {
                let (b, a) = local(i);
                let side = usize::from(b < 0.0);
                if b.abs() <= nearest_b[side] + d {
                    let wall = &mut walls[side];
                    wall.0 += 1;
                    wall.1 = wall.1.min(a);
                    wall.2 = wall.2.max(a);
                }
            }
            walls
                .iter()
                .all(|&(count, lo_a, hi_a)| count >= MIN_SAMPLES && hi_a - lo_a >= 2.0 * d)
                .then_some(Strip {
                    across,
                    near: d,
                    far: nearest_b[1],
                })
        })
        .collect();
    Corridors { strips, field }
}

/// Which side of the tube `{d < delta}` around the data a vertex lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// In a region outside the tube labelled outside the curve.
    Outside,
    /// In a region outside the tube labelled inside the curve.
    Inside,
    /// In the tube, or in a pocket of it (a free region never farther than `2 delta`
    /// from the data, such as the space between noisy samples).
    Tube,
}

/// Labels each vertex of `mesh` by its side of the tube of radius `delta` around the
/// data (`dist`: the distance to the data at each vertex; `neighbours(v)`: its ring),
/// the vertices where `corridor` is true (see [`corridors`]; empty for none) taken out
/// of the tube. The regions outside the tube are outside or inside by how many tube
/// crossings separate them from the domain boundary. `None` when no region comes out
/// inside (the tube leaks, or the data encloses nothing).
pub fn tube_sides<'a>(
    mesh: &Mesh,
    neighbours: impl Fn(usize) -> &'a [u32],
    dist: &[f64],
    delta: f64,
    corridor: Option<&Corridors<'_>>,
) -> Option<Vec<Side>> {
    let n = dist.len();
    const NONE: u32 = u32::MAX;
    // Label connected regions of free (d >= delta) and tube vertices separately.
    // Two free vertices are joined only by an edge that runs along the corridors they
    // lie in, not across a wall between two of them.
    let joined = |v: usize, w: usize| {
        let along = |a: usize, b: usize| match strip_at(corridor, a) {
            Some(strip) => strip.holds(mesh.coords[a], mesh.coords[b]),
            None => true,
        };
        along(v, w) && along(w, v)
    };
    let label = |free_at: &dyn Fn(usize) -> bool| -> (Vec<u32>, Vec<bool>) {
        let mut region = vec![NONE; n];
        let mut kinds = Vec::new(); // true: free
        let mut stack = Vec::new();
        for seed in 0..n {
            if region[seed] != NONE {
                continue;
            }
            let free = free_at(seed);
            let id = kinds.len() as u32;
            kinds.push(free);
            region[seed] = id;
            stack.push(seed);
            while let Some(v) = stack.pop() {
                for &w in neighbours(v) {
                    let w = w as usize;
                    if region[w] == NONE && free_at(w) == free && (!free || joined(v, w)) {
                        region[w] = id;
                        stack.push(w);
                    }
                }
            }
        }
        (region, kinds)
    };
    // Free pockets between noisy samples, never farther than 2 delta from the data,
    // are part of the tube, not regions of their own.
    let (first, first_kinds) = label(&|v| dist[v] >= delta);
    let mut reach = vec![0.0f64; first_kinds.len()];
    for v in 0..n {
        let r = first[v] as usize;
        reach[r] = reach[r].max(dist[v]);
    }
    let free_at = |v: usize| {
        let r = first[v] as usize;
        (first_kinds[r] && reach[r] >= 2.0 * delta) || strip_at(corridor, v).is_some()
    };
    let (mut region, kinds) = label(&free_at);
    if let Some(c) = corridor {
        let free: Vec<bool> = region.iter().map(|&r| kinds[r as usize]).collect();
        bridge_corridors(mesh, c, &free, &mut region);
    }
    // Depth of each region from the free regions touching the boundary: one step into or
    // out of the tube, two across a wall between corridors (through the tube it is).
    let nr = kinds.len();
    let depth = region_depths(mesh, &neighbours, &region, &kinds);
    // Free regions at depth 0, 4, 8, ... are outside; 2, 6, ... inside. Unreached
    // regions (a domain with no free boundary) count as inside.
    // An inside region counts as enclosed only if some vertex of it lies at least
    // delta / 2 from the data and it has a few vertices: a speck left where a leaking
    // tube pinched is no interior, and a wider tube must be tried.
    let mut size = vec![0u32; nr];
    let mut region_reach = vec![0.0f64; nr];
    for (v, &r) in region.iter().enumerate() {
        size[r as usize] += 1;
        region_reach[r as usize] = region_reach[r as usize].max(dist[v]);
    }
    let any_inside = (0..nr).any(|r| {
        kinds[r]
            && size[r] >= 3
            && region_reach[r] >= 0.5 * delta
            && (depth[r] == u32::MAX || (depth[r] / 2) % 2 == 1)
    });
    if !any_inside {
        return None;
    }
    let sides = region
        .iter()
        .map(|&r| {
            let r = r as usize;
            match (kinds[r], depth[r]) {
                (false, _) => Side::Tube,
                (true, d) if d != u32::MAX && (d / 2) % 2 == 0 => Side::Outside,
                (true, _) => Side::Inside,
            }
        })
        .collect();
    Some(sides)
}

/// The depth of each region (`region` per vertex, `kinds[r]` whether region `r` is
/// free) from the free regions touching the domain's boundary, `u32::MAX` where none
/// reaches.
fn region_depths<'a>(
    mesh: &Mesh,
    neighbours: impl Fn(usize) -> &'a [u32],
    region: &[u32],
    kinds: &[bool],
) -> Vec<u32> {
    let n = region.len();
    let nr = kinds.len();
    let mut adj: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nr];
    for v in 0..n {
        for &w in neighbours(v) {
            let (a, b) = (region[v], region[w as usize]);
            if a != b {
                let step = if kinds[a as usize] && kinds[b as usize] {
                    2
                } else {
                    1
                };
                adj[a as usize].push((b, step));
            }
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    let mut depth = vec![u32::MAX; nr];
    let mut queue = std::collections::BinaryHeap::new();
    for (&rv, &tag) in region.iter().zip(&mesh.tag) {
        let r = rv as usize;
        if tag != VertexTag::Interior && kinds[r] && depth[r] == u32::MAX {
            depth[r] = 0;
            queue.push(std::cmp::Reverse((0, r)));
        }
    }
    while let Some(std::cmp::Reverse((dr, r))) = queue.pop() {
        if dr > depth[r] {
            continue;
        }
        for &(q, step) in &adj[r] {
            let q = q as usize;
            if dr + step < depth[q] {
                depth[q] = dr + step;
                queue.push(std::cmp::Reverse((depth[q], q)));
            }
        }
    }
    depth
}

/// Joins the regions of free vertices that one corridor runs through but that the
/// mesh's edges do not join: where the corridor test failed for a stretch (a gap in a
/// wall, a noisy patch), and where a corridor opens into a wider free region through
/// the tube (its mouth). A corridor vertex joins the free vertices within `3 d` of it
/// inside its strip (and, if they are corridor vertices, with it inside theirs) when the
/// segment between them keeps `d / 2` from every sample; `region` is relabelled to the
/// representatives. Walls still separate: across one neither the strips nor the
/// clearance hold.
fn bridge_corridors(mesh: &Mesh, corridor: &Corridors<'_>, free: &[bool], region: &mut [u32]) {
    let ids: Vec<usize> = (0..region.len()).filter(|&v| free[v]).collect();
    if ids.len() < 2 || !ids.iter().any(|&v| strip_at(Some(corridor), v).is_some()) {
        return;
    }
    let coords: Vec<Point> = ids.iter().map(|&v| mesh.coords[v]).collect();
    let Ok(tree) = DistanceField::new(&coords) else {
        return;
    };
    // The tree orders its (distinct) points by x then y: map them back to vertices.
    let mut by_point = ids.clone();
    by_point.sort_unstable_by(|&a, &b| {
        let (p, q) = (mesh.coords[a], mesh.coords[b]);
        p[0].total_cmp(&q[0]).then(p[1].total_cmp(&q[1]))
    });
    let regions = region.iter().copied().max().map_or(0, |m| m + 1);
    let mut parent: Vec<u32> = (0..regions).collect();
    let mut near = Vec::new();
    for &v in &ids {
        let Some(sv) = strip_at(Some(corridor), v) else {
            continue;
        };
        let p = mesh.coords[v];
        tree.within(p, 3.0 * sv.near, &mut near);
        for &j in &near {
            let w = by_point[j as usize];
            let q = mesh.coords[w];
            let (a, b) = (root(&mut parent, region[v]), root(&mut parent, region[w]));
            if a == b || !sv.holds(p, q) {
                continue;
            }
            let mutual = strip_at(Some(corridor), w).is_none_or(|sw| sw.holds(q, p));
            if mutual && corridor.clear(p, q, 0.5 * sv.near) {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    for r in region.iter_mut() {
        *r = root(&mut parent, *r);
    }
}

/// The tube start: `dist` is the distance to the data at each vertex of `mesh`,
/// `neighbours(v)` its ring. Returns a level set whose zero isoline is the boundary
/// between the regions labelled outside and the rest; it is a signed distance only up
/// to the tube, so renormalize it before use. `None` when no region comes out inside
/// (the tube leaks, or the data encloses nothing): use an enclosing start then.
pub fn tube<'a>(
    mesh: &Mesh,
    neighbours: impl Fn(usize) -> &'a [u32],
    dist: &[f64],
    delta: f64,
    corridor: Option<&Corridors<'_>>,
) -> Option<Vec<f64>> {
    let sides = tube_sides(mesh, neighbours, dist, delta, corridor)?;
    let u = sides
        .iter()
        .zip(dist)
        .enumerate()
        .map(|(v, (side, &d))| match side {
            Side::Outside => d - radius_at(v, d, delta, corridor),
            Side::Inside => -d,
            Side::Tube => (d - delta).min(-f64::EPSILON),
        })
        .collect();
    Some(u)
}

/// The tube's radius at vertex `v` (distance `d` from the data): `delta`, and in a
/// corridor half the distance, so that the corridor's vertices lie outside it.
fn radius_at(v: usize, d: f64, delta: f64, corridor: Option<&Corridors<'_>>) -> f64 {
    if strip_at(corridor, v).is_some() {
        delta.min(0.5 * d)
    } else {
        delta
    }
}

/// The medial start: the curve midway across the tube of radius `delta`, between its
/// boundary with the outside regions and its boundary with the inside regions (see
/// [`tube_sides`]). The tube is the union of the discs around the samples, so its middle
/// runs through the middle of the noise band: the curve starts at the data rather than
/// `delta` away from it, and the evolution has nothing left to capture.
///
/// `u = (a - b) / 2`, with `a` and `b` the signed distances (fast marching, within
/// `4 delta` of the tube) to the tube's outer and inner boundaries; it is a signed
/// distance only near the curve, so renormalize it before use. A stretch of tube with
/// no inside on either side (a whisker, an open end) comes out outside. `None` as for
/// [`tube`].
pub fn medial(
    mesh: &Mesh,
    space: &P1Space,
    dist: &[f64],
    delta: f64,
    corridor: Option<&Corridors<'_>>,
    fm: &mut Redistancer,
) -> Option<Vec<f64>> {
    let sides = tube_sides(mesh, |v| space.ring(v), dist, delta, corridor)?;
    let mut boundary = |of: Side| -> Vec<f64> {
        let mut phi: Vec<f64> = sides
            .iter()
            .zip(dist)
            .enumerate()
            .map(|(v, (&side, &d))| {
                if side == of {
                    d - radius_at(v, d, delta, corridor)
                } else {
                    // Everything else is the far side of the boundary: the tube
                    // (pockets included) and the regions of the other label.
                    (d - delta).min(-f64::EPSILON)
                }
            })
            .collect();
        fm.run(mesh, space, &mut phi, 4.0 * delta);
        phi
    };
    let a = boundary(Side::Outside);
    let b = boundary(Side::Inside);
    Some(a.iter().zip(&b).map(|(a, b)| 0.5 * (a - b)).collect())
}

/// The free-space start of a scan frame: negative in the space the rays swept (see
/// [`FreeSpace`]), positive behind the returns and outside the field of view; a signed
/// distance to the free space's boundary, exact at every vertex up to `limit` from it
/// (vertices beyond keep their sign at `limit`; pass `f64::INFINITY` for the distance
/// everywhere).
pub fn free_space(mesh: &Mesh, free: &FreeSpace, limit: f64) -> Vec<f64> {
    // The exact distance at every vertex, not only at those by a change of sign with
    // fast marching from them: the boundary's segments near a point are found by its
    // bearing, and measuring them costs less than a march does.
    let boundary = free.boundary();
    mesh.coords
        .par_iter()
        .map(|&p| boundary.signed_within(p, limit))
        .collect()
}

/// Signed distance to the circle of centre `c` and radius `r`.
pub fn circle(c: Point, r: f64, coords: &[Point]) -> Vec<f64> {
    coords.par_iter().map(|&p| dist(p, c) - r).collect()
}

/// Signed distance to the rectangle of centre `c` and half-sizes `half`, its corners
/// rounded with radius `round` (at most the smaller half-size).
pub fn rounded_box(c: Point, half: Point, round: f64, coords: &[Point]) -> Vec<f64> {
    let r = round.min(half[0]).min(half[1]).max(0.0);
    let inner = [half[0] - r, half[1] - r];
    coords
        .par_iter()
        .map(|&p| {
            let q = [
                (p[0] - c[0]).abs() - inner[0],
                (p[1] - c[1]).abs() - inner[1],
            ];
            let outside = (q[0].max(0.0).powi(2) + q[1].max(0.0).powi(2)).sqrt();
            outside + q[0].max(q[1]).min(0.0) - r
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::tube_radius;
    use crate::geom::Polyline;

    /// Signed distance to a set of polylines: the distance to the nearest segment, negative
    /// inside by the even-odd rule over the closed polylines (open ones only attract).
    fn polylines(curves: &[Polyline], coords: &[Point]) -> Vec<f64> {
        let index = crate::index::SegmentIndex::new(curves);
        let closed: Vec<&Polyline> = curves.iter().filter(|c| c.closed).collect();
        coords
            .par_iter()
            .map(|&p| {
                let d = index.distance(p);
                let inside = closed.iter().fold(false, |acc, c| acc ^ c.encloses(p));
                if inside {
                    -d
                } else {
                    d
                }
            })
            .collect()
    }

    #[test]
    fn starting_curves_are_signed_distances_enclosing_the_data() {
        let pts = vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0], [1.0, 0.5]];
        let probes = vec![[1.0, 0.5], [3.0, 0.5], [1.0, -1.0], [-0.3, 0.5]];
        for init in [Init::Circle, Init::Box] {
            let at_data = enclosing(init, &pts, 0.1, &pts);
            assert!(
                at_data.iter().all(|&u| u <= -0.1 + 1e-12),
                "{init:?} {at_data:?}"
            );
        }
        let b = enclosing(Init::Box, &pts, 0.1, &probes);
        assert!((b[0] + 0.6).abs() < 1e-12);
        assert!((b[1] - 0.9).abs() < 1e-12);
        assert!((b[2] - 0.9).abs() < 1e-12);
        assert!((b[3] - 0.2).abs() < 1e-12);
        let c = enclosing(Init::Circle, &pts, 0.1, &probes);
        let r = 5f64.sqrt() / 2.0 + 0.1;
        assert!((c[0] + r).abs() < 1e-12);
    }

    #[test]
    fn tube_start_finds_holes_and_separate_components() {
        // Points on two concentric circles (an annulus) and on a separate small circle.
        let mut pts = Vec::new();
        for i in 0..400 {
            let a = i as f64 / 400.0 * std::f64::consts::TAU;
            pts.push([0.4 * a.cos(), 0.4 * a.sin()]);
            pts.push([0.2 * a.cos(), 0.2 * a.sin()]);
            pts.push([0.75 + 0.1 * a.cos(), 0.1 * a.sin()]);
        }
        let field = DistanceField::new(&pts).unwrap();
        let mesh = Mesh::structured(
            &BBox {
                min: [-0.6, -0.6],
                max: [1.0, 0.6],
            },
            160,
        );
        let space = crate::fem::P1Space::new(&mesh);
        let mut d = Vec::new();
        field.distances_into(&mesh.coords, &mut d);
        let delta = tube_radius(&field, 0.02);
        assert!((0.02..0.03).contains(&delta), "{delta}");
        // A tube too thin to close: nothing is inside.
        assert!(tube(&mesh, |v| space.ring(v), &d, 1e-4, None).is_none());
        let u = tube(&mesh, |v| space.ring(v), &d, delta, None).unwrap();
        let at = |p: Point| {
            let v = (0..mesh.coords.len())
                .min_by(|&a, &b| dist(mesh.coords[a], p).total_cmp(&dist(mesh.coords[b], p)))
                .unwrap();
            u[v]
        };
        assert!(at([0.0, 0.0]) > 0.0, "the hole is outside");
        assert!(at([0.3, 0.0]) < 0.0, "the ring is inside");
        assert!(at([0.75, 0.0]) < 0.0, "the small disc is inside");
        assert!(
            at([0.5, 0.5]) > 0.0 && at([0.62, 0.0]) > 0.0,
            "the gap is outside"
        );
    }

    /// Samples every `step` along `curves`, in order.
    fn along(curves: &[Polyline], step: f64) -> Vec<Point> {
        let mut pts = Vec::new();
        for c in curves {
            for (a, b) in c.segments() {
                let n = (dist(a, b) / step).ceil().max(1.0) as usize;
                pts.extend((0..n).map(|i| {
                    let f = i as f64 / n as f64;
                    [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f]
                }));
            }
        }
        pts
    }

    #[test]
    fn corridors_lie_between_two_walls_not_in_a_hole_of_one() {
        // Two walls 0.05 apart sampled every 0.005, the lower one with a hole 0.05 long
        // to the right; beyond x = 0.6 the lower wall alone.
        let mut pts = Vec::new();
        for i in 0..=200 {
            let x = i as f64 * 0.005;
            if !(0.7..0.75).contains(&x) {
                pts.push([x, 0.0]);
            }
            if x <= 0.6 {
                pts.push([x, 0.05]);
            }
        }
        let field = DistanceField::new(&pts).unwrap();
        let probes = [
            [0.3, 0.025],
            [0.3, 0.02],
            [0.725, 0.0],
            [0.725, 0.01],
            [0.3, 0.003],
        ];
        let near = field.nearest_all(&probes);
        let d: Vec<f64> = near.iter().map(|n| n.dist).collect();
        let j: Vec<u32> = near.iter().map(|n| n.index).collect();
        let c = corridors(&field, &probes, &d, &j, 0.001, 1.0).strips;
        assert!(c[0].is_some() && c[1].is_some(), "mid-corridor: {c:?}");
        let strip = c[0].unwrap();
        assert!((strip.near - 0.025).abs() < 1e-12 && (strip.far - 0.025).abs() < 1e-12);
        assert!(
            c[2].is_none() && c[3].is_none(),
            "a hole in one wall is no corridor: {c:?}"
        );
        assert!(c[4].is_none(), "too near a wall to see the other: {c:?}");
    }

    #[test]
    fn corridors_keep_an_inlet_narrower_than_the_tube_open() {
        // The simulator's disc with three bays, inlets 0.02 wide, sampled every 0.004:
        // a tube of radius 0.015 closes the inlets and fills the bays.
        let truth: Vec<Polyline> = isoline_sim::Shape::Bays
            .truth(0.02)
            .into_iter()
            .map(|pl| Polyline {
                closed: pl.closed,
                points: pl.points,
            })
            .collect();
        let pts = along(&truth, 0.004);
        let field = DistanceField::new(&pts).unwrap();
        let bbox = BBox {
            min: [0.0, 0.0],
            max: [1.0, 1.0],
        };
        let mesh = Mesh::structured(&bbox, 250);
        let space = P1Space::new(&mesh);
        let near = field.nearest_all(&mesh.coords);
        let d: Vec<f64> = near.iter().map(|n| n.dist).collect();
        let j: Vec<u32> = near.iter().map(|n| n.index).collect();
        let delta = 0.015;
        let at = |sides: &[Side], p: Point| {
            let v = (0..mesh.coords.len())
                .min_by(|&a, &b| dist(mesh.coords[a], p).total_cmp(&dist(mesh.coords[b], p)))
                .unwrap();
            sides[v]
        };
        // The first bay's centre and its inlet's middle; the body between two bays.
        let (bay, inlet, body) = ([0.5, 0.7], [0.5, 0.85], [0.5, 0.45]);
        let closed = tube_sides(&mesh, |v| space.ring(v), &d, delta, None).unwrap();
        assert_eq!(
            at(&closed, bay),
            Side::Inside,
            "without corridors the bay fills"
        );
        let c = corridors(&field, &mesh.coords, &d, &j, 0.004, 2.0 * delta);
        let open = tube_sides(&mesh, |v| space.ring(v), &d, delta, Some(&c)).unwrap();
        assert_eq!(at(&open, bay), Side::Outside);
        assert_eq!(at(&open, inlet), Side::Outside);
        assert_eq!(at(&open, body), Side::Inside);
    }

    #[test]
    fn medial_start_runs_through_the_data_and_drops_whiskers() {
        // A circle of radius 0.3 with a radial whisker out to 0.5, on a mesh of size h.
        let mut pts = Vec::new();
        for i in 0..600 {
            let a = i as f64 / 600.0 * std::f64::consts::TAU;
            pts.push([0.3 * a.cos(), 0.3 * a.sin()]);
        }
        for i in 0..60 {
            pts.push([0.3 + 0.2 * i as f64 / 60.0, 0.0]);
        }
        let field = DistanceField::new(&pts).unwrap();
        let bbox = BBox {
            min: [-0.6, -0.6],
            max: [0.6, 0.6],
        };
        let n = 120;
        let h = 1.2 / n as f64;
        let mesh = Mesh::structured(&bbox, n);
        let space = P1Space::new(&mesh);
        let mut d = Vec::new();
        field.distances_into(&mesh.coords, &mut d);
        let delta = 3.0 * h;
        let mut fm = Redistancer::new();
        let mut u = medial(&mesh, &space, &d, delta, None, &mut fm).unwrap();
        fm.run(&mesh, &space, &mut u, f64::INFINITY);
        // The tube's middle is the circle itself, up to the first-order error of fast
        // marching and of the P1 tube boundaries: O(h) each.
        let circle: Vec<Point> = pts[..600].to_vec();
        let at = crate::fem::locate::locate_all(&mesh, &circle);
        let worst = at
            .iter()
            .map(|l| l.interpolate(&mesh, &u).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1.5 * h, "{worst} against h = {h}");
        let at = crate::fem::locate::locate_all(&mesh, &[[0.0, 0.0], [0.45, 0.0], [0.5, 0.5]]);
        let u: Vec<f64> = at.iter().map(|l| l.interpolate(&mesh, &u)).collect();
        assert!(u[0] < -0.25, "the disc is inside: {u:?}");
        assert!(u[1] > 0.0, "the whisker is outside: {u:?}");
        assert!(u[2] > 0.0, "{u:?}");
    }

    #[test]
    fn polyline_distance_is_negative_inside_and_handles_holes() {
        let square = |h: f64| Polyline {
            closed: true,
            points: vec![[-h, -h], [h, -h], [h, h], [-h, h]],
        };
        let curves = vec![square(2.0), square(1.0)];
        let u = polylines(&curves, &[[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [0.0, 1.25]]);
        assert!(
            (u[0] - 1.0).abs() < 1e-12,
            "inside the hole is outside: {u:?}"
        );
        assert!((u[1] + 0.5).abs() < 1e-12);
        assert!((u[2] - 1.0).abs() < 1e-12);
        assert!((u[3] + 0.25).abs() < 1e-12);
    }
}

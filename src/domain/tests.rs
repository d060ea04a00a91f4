//! Property tests of the extended-domain geometry against brute-force twins (issue 4): random
//! simple polygons with holes, some snapped to a dyadic grid so that query points fall exactly on
//! vertices and edges. Fixed proptest seeds: every run checks the same cases.

use super::coverage::{box_coverage, ElementStatus, StBox};
use super::extended::{locate_by_winding, ExtendedDomain};
use super::hull::convex_hull;
use super::parallelogram::{min_area_parallelogram, NEAR_MINIMAL_REL};
use super::predicates::{orient, signed_area};
use super::trapezoidal_map::{Location, TrapezoidalMap};
use crate::faces::geom::on_segment;
use crate::shuffle::SplitMix64;
use glam::{DVec2, DVec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

fn config(cases: u32, seed: u64) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..Config::default()
    }
}

/// A small deterministic generator for the polygons (proptest drives its seed): the crate's
/// SplitMix64, with the draws the polygons need.
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }
    /// Uniform in [0, 1).
    fn f(&mut self) -> f64 {
        (self.0.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.f() * n as f64) as usize % n.max(1)
    }
}

/// Grid of the snapped polygons: coordinates are multiples of 1/256, so edge midpoints are exact.
const GRID: f64 = 256.0;

/// A star-shaped ring around `centre`: `n` vertices at jittered angles, radii in `[r_lo, r_hi]`,
/// counter-clockwise.
fn star(rng: &mut Rng, centre: DVec2, n: usize, r_lo: f64, r_hi: f64) -> Vec<DVec2> {
    // Jitter small enough that every angular gap is below pi: the ring winds once around centre.
    let jitter = if n < 5 { 0.4 } else { 0.8 };
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * (i as f64 + rng.range(0.0, jitter)) / n as f64;
            centre + DVec2::from_angle(a) * rng.range(r_lo, r_hi)
        })
        .collect()
}

/// A random simple polygon with holes inside `[0,1]^2`: outer ring counter-clockwise, holes
/// clockwise, disjoint and inside it. `None` when snapping broke simplicity.
fn random_polygon(
    seed: u64,
    n_outer: usize,
    n_holes: usize,
    snap: bool,
) -> Option<Vec<Vec<DVec2>>> {
    let mut rng = Rng::new(seed);
    let c = DVec2::splat(0.5);
    let mut rings = vec![star(&mut rng, c, n_outer, 0.25, 0.48)];
    // With >= 5 vertices the outer star contains the disc of radius 0.25 * cos(0.9 * TAU / 5).
    if n_outer >= 5 {
        let cells = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)];
        let mut order: Vec<usize> = (0..4).collect();
        for i in (1..4).rev() {
            order.swap(i, rng.below(i + 1));
        }
        for &k in order.iter().take(n_holes.min(4)) {
            let (dx, dy) = cells[k];
            let centre = c + DVec2::new(dx, dy) * 0.037;
            let m = 3 + rng.below(6);
            let mut hole = star(&mut rng, centre, m, 0.012, 0.034);
            hole.reverse();
            rings.push(hole);
        }
    }
    if snap {
        for ring in &mut rings {
            for p in ring.iter_mut() {
                *p = (*p * GRID).round() / GRID;
            }
            ring.dedup();
        }
    }
    is_valid_polygon(&rings).then_some(rings)
}

/// Brute force: rings have >= 3 vertices, the right orientations, and no two edges meet except
/// consecutive edges of one ring at their shared vertex.
fn is_valid_polygon(rings: &[Vec<DVec2>]) -> bool {
    let mut edges = Vec::new();
    for (r, ring) in rings.iter().enumerate() {
        if ring.len() < 3 || (signed_area(ring) > 0.0) != (r == 0) {
            return false;
        }
        let n = ring.len();
        for i in 0..n {
            edges.push((r, i, n, ring[i], ring[(i + 1) % n]));
        }
    }
    for (x, &(r1, i1, n1, a, b)) in edges.iter().enumerate() {
        for &(r2, i2, _, c, d) in &edges[x + 1..] {
            let adjacent = r1 == r2 && (i2 == (i1 + 1) % n1 || i1 == (i2 + 1) % n1);
            let o1 = orient(a, b, c);
            let o2 = orient(a, b, d);
            let o3 = orient(c, d, a);
            let o4 = orient(c, d, b);
            if adjacent {
                // Only the shared vertex: not folded back along each other.
                if o1 == 0.0 && o2 == 0.0 {
                    return false;
                }
                continue;
            }
            let proper = o1 * o2 < 0.0 && o3 * o4 < 0.0;
            let touch = on_segment(a, b, c)
                || on_segment(a, b, d)
                || on_segment(c, d, a)
                || on_segment(c, d, b);
            if proper || touch {
                return false;
            }
        }
    }
    // Holes inside the outer ring and outside each other (enough: no edges meet).
    rings[1..]
        .iter()
        .all(|h| twin_locate(&rings[..1], h[0]) == Location::Inside)
        && rings[1..].iter().enumerate().all(|(i, h)| {
            rings[1..].iter().enumerate().all(|(j, g)| {
                i == j
                    || twin_locate(&[g.iter().rev().copied().collect()], h[0]) == Location::Outside
            })
        })
}

/// The brute-force twin of point location: crossing-number parity (even-odd) with exact
/// orientation, the closed boundary first. Independent of the map and of the winding fallback.
fn twin_locate(rings: &[Vec<DVec2>], p: DVec2) -> Location {
    let mut inside = false;
    for ring in rings {
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            if on_segment(a, b, p) {
                return Location::Boundary;
            }
            // Half-open rule on y: the edge crosses the horizontal line through p.
            if (a.y > p.y) != (b.y > p.y) {
                // Crossing right of p: p is left of the edge directed upward.
                let (lo, hi) = if a.y < b.y { (a, b) } else { (b, a) };
                if orient(lo, hi, p) > 0.0 {
                    inside = !inside;
                }
            }
        }
    }
    if inside {
        Location::Inside
    } else {
        Location::Outside
    }
}

/// Query points: vertices, exact points on edges (snapped polygons), grid points, random points.
fn query_points(rng: &mut Rng, rings: &[Vec<DVec2>], count: usize) -> Vec<DVec2> {
    let mut pts = Vec::with_capacity(count + 64);
    for ring in rings {
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            pts.push(a);
            pts.push(0.5 * (a + b));
            pts.push(a + 0.25 * (b - a));
            // Same x or y as a vertex, just off it.
            pts.push(DVec2::new(a.x, a.y + 1.0 / GRID));
            pts.push(DVec2::new(a.x - 1.0 / GRID, a.y));
        }
    }
    for _ in 0..count {
        match rng.below(3) {
            0 => pts.push(DVec2::new(rng.range(-0.1, 1.1), rng.range(-0.1, 1.1))),
            1 => pts.push((DVec2::new(rng.f(), rng.f()) * GRID).round() / GRID),
            _ => {
                let r = &rings[rng.below(rings.len())];
                let a = r[rng.below(r.len())];
                pts.push(a + DVec2::new(rng.range(-0.05, 0.05), rng.range(-0.05, 0.05)));
            }
        }
    }
    pts
}

/// The area of the polygon with holes inside a box: Sutherland-Hodgman on each ring against the
/// box, summing signed areas (exact for a convex clip window up to rounding). Slow and simple.
fn clipped_area(rings: &[Vec<DVec2>], b: &StBox) -> f64 {
    let mut total = 0.0;
    for ring in rings {
        let mut poly = ring.clone();
        // (inside test, intersection) for each of the four half-planes.
        for side in 0..4 {
            if poly.is_empty() {
                break;
            }
            let inside = |p: DVec2| match side {
                0 => p.x >= b.min.x,
                1 => p.x <= b.max.x,
                2 => p.y >= b.min.y,
                _ => p.y <= b.max.y,
            };
            let cut = |p: DVec2, q: DVec2| {
                let (pv, qv, level) = match side {
                    0 => (p.x, q.x, b.min.x),
                    1 => (p.x, q.x, b.max.x),
                    2 => (p.y, q.y, b.min.y),
                    _ => (p.y, q.y, b.max.y),
                };
                let t = (level - pv) / (qv - pv);
                let mut x = p + (q - p) * t;
                if side < 2 {
                    x.x = level;
                } else {
                    x.y = level;
                }
                x
            };
            let mut out = Vec::with_capacity(poly.len() + 4);
            for i in 0..poly.len() {
                let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
                match (inside(p), inside(q)) {
                    (true, true) => out.push(q),
                    (true, false) => out.push(cut(p, q)),
                    (false, true) => {
                        out.push(cut(p, q));
                        out.push(q);
                    }
                    (false, false) => {}
                }
            }
            poly = out;
        }
        total += signed_area(&poly);
    }
    total
}

fn random_box(rng: &mut Rng, rings: &[Vec<DVec2>]) -> StBox {
    match rng.below(4) {
        // A dyadic element of the unit square.
        0 => {
            let level = rng.below(6) as i32;
            let n = 2f64.powi(level);
            let (i, j) = (rng.below(n as usize) as f64, rng.below(n as usize) as f64);
            StBox::new(DVec2::new(i, j) / n, DVec2::new(i + 1.0, j + 1.0) / n)
        }
        // Edges on the polygon's own coordinates (degenerate contacts).
        1 => {
            let r = &rings[rng.below(rings.len())];
            let a = r[rng.below(r.len())];
            let c = r[rng.below(r.len())];
            StBox::new(a.min(c), a.max(c) + DVec2::splat(1.0 / GRID))
        }
        // Small boxes near the boundary.
        2 => {
            let r = &rings[rng.below(rings.len())];
            let a = r[rng.below(r.len())];
            let lo = a - DVec2::new(rng.range(0.0, 0.03), rng.range(0.0, 0.03));
            StBox::new(
                lo,
                lo + DVec2::new(rng.range(0.001, 0.05), rng.range(0.001, 0.05)),
            )
        }
        _ => {
            let lo = DVec2::new(rng.range(-0.2, 1.0), rng.range(-0.2, 1.0));
            StBox::new(
                lo,
                lo + DVec2::new(rng.range(0.0, 0.7), rng.range(0.0, 0.7)),
            )
        }
    }
}

/// A random affine map of the plane (rotation, anisotropic scale, shear, translation) with a
/// positive determinant, so polygons keep orientation and simplicity.
fn random_affine(rng: &mut Rng) -> impl Fn(DVec2) -> DVec2 {
    let rot = DVec2::from_angle(rng.range(0.0, std::f64::consts::TAU));
    let (sx, sy) = (rng.range(0.3, 4.0), rng.range(0.3, 4.0));
    let shear = rng.range(-1.0, 1.0);
    let offset = DVec2::new(rng.range(-50.0, 50.0), rng.range(-50.0, 50.0));
    move |p: DVec2| offset + rot.rotate(DVec2::new(sx * p.x + shear * p.y, sy * p.y))
}

proptest! {
    #![proptest_config(config(1500, 0x1551_0e40))]

    /// The map's point location equals the crossing-number twin everywhere, boundary included.
    #[test]
    fn map_locates_like_the_crossing_number_twin(
        seed in any::<u64>(), n_outer in 3usize..48, n_holes in 0usize..5, snap in any::<bool>()
    ) {
        let Some(rings) = random_polygon(seed, n_outer, n_holes, snap) else { return Ok(()) };
        let map = TrapezoidalMap::new_checked(&rings).expect("a valid polygon has a map");
        let mut rng = Rng::new(seed ^ 0xabcd);
        for p in query_points(&mut rng, &rings, 60) {
            let twin = twin_locate(&rings, p);
            prop_assert_eq!(map.locate(p), twin, "point {:?}", p);
            prop_assert_eq!(locate_by_winding(&rings, p), twin, "winding fallback at {:?}", p);
        }
    }
}

proptest! {
    #![proptest_config(config(600, 0xc0fe_7a9e))]

    /// Coverage of random boxes equals the clipped area, and the status agrees with it.
    #[test]
    fn coverage_equals_the_clipped_area(
        seed in any::<u64>(), n_outer in 3usize..40, n_holes in 0usize..5, snap in any::<bool>()
    ) {
        let Some(rings) = random_polygon(seed, n_outer, n_holes, snap) else { return Ok(()) };
        let map = TrapezoidalMap::new(&rings).expect("a valid polygon has a map");
        let mut rng = Rng::new(seed ^ 0x1234);
        let mut total = 0.0;
        let n = 8;
        for i in 0..n {
            for j in 0..n {
                let b = StBox::new(DVec2::new(i as f64, j as f64) / n as f64,
                                   DVec2::new(i as f64 + 1.0, j as f64 + 1.0) / n as f64);
                total += box_coverage(&rings, b, |p| map.contains(p)).area;
            }
        }
        let face: f64 = rings.iter().map(|r| signed_area(r)).sum();
        prop_assert!((total - face).abs() < 1e-12, "elements sum to {} for a face of {}", total, face);
        for _ in 0..25 {
            let b = random_box(&mut rng, &rings);
            let c = box_coverage(&rings, b, |p| map.contains(p));
            let oracle = clipped_area(&rings, &b).max(0.0);
            prop_assert!((c.area - oracle).abs() <= 1e-12, "box {:?}: {} vs clipped {}", b, c.area, oracle);
            match c.status {
                ElementStatus::Full => prop_assert!((oracle - b.area()).abs() <= 1e-12),
                ElementStatus::Empty => prop_assert!(oracle <= 1e-12),
                ElementStatus::Partial => {}
            }
            // A box holding clearly some face and some non-face is partial.
            if oracle > 1e-9 && oracle < b.area() - 1e-9 {
                prop_assert_eq!(c.status, ElementStatus::Partial);
            }
            prop_assert!((0.0..=1.0).contains(&c.fraction(&b)));
        }
    }
}

/// Brute force: the minimal area over all pairs of hull-edge directions, and the best |sin| among
/// pairs within `rel` of it.
fn brute_force_parallelogram(points: &[DVec2], rel: f64) -> (f64, f64) {
    // Hull edges by brute force: ordered pairs with every point on the left or on the line.
    let mut dirs = Vec::new();
    for (i, &a) in points.iter().enumerate() {
        for (j, &b) in points.iter().enumerate() {
            if i != j && a != b && points.iter().all(|&c| orient(a, b, c) >= 0.0) {
                dirs.push((b - a).normalize());
            }
        }
    }
    let width = |d: DVec2| {
        let n = d.perp();
        let (lo, hi) = points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(n.dot(*p)), hi.max(n.dot(*p)))
            });
        hi - lo
    };
    let mut pairs = Vec::new();
    for &d1 in &dirs {
        for &d2 in &dirs {
            let sin = d1.perp_dot(d2).abs();
            if sin > 1e-9 {
                pairs.push((width(d1) * width(d2) / sin, sin));
            }
        }
    }
    let min = pairs.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let best_sin = pairs
        .iter()
        .filter(|p| p.0 <= min * (1.0 + rel))
        .map(|p| p.1)
        .fold(0.0, f64::max);
    (min, best_sin)
}

proptest! {
    #![proptest_config(config(1500, 0x9a7a_11e1))]

    /// The parallelogram encloses every point, is within 0.1% of the brute-force optimum over all
    /// pairs of hull-edge directions, and no near-minimal candidate has an angle closer to 90.
    #[test]
    fn parallelogram_is_near_minimal_and_closest_to_square(
        seed in any::<u64>(), n in 3usize..30, kind in 0usize..3
    ) {
        let mut rng = Rng::new(seed);
        let affine = random_affine(&mut rng);
        let points: Vec<DVec2> = match kind {
            0 => (0..n).map(|_| DVec2::new(rng.f(), rng.f())).collect(),
            1 => star(&mut rng, DVec2::ZERO, n, 0.3, 1.0),
            // Regular polygons: many equal candidates.
            _ => (0..n).map(|i| DVec2::from_angle(std::f64::consts::TAU * i as f64 / n as f64)).collect(),
        };
        let points: Vec<DVec2> = points.into_iter().map(&affine).collect();
        let p = min_area_parallelogram(&points);
        prop_assert!(p.area() > 0.0 && p.origin.is_finite() && p.u.is_finite() && p.v.is_finite());
        for q in &points {
            let st = p.coordinates(*q);
            prop_assert!(st.min_element() >= -1e-9 && st.max_element() <= 1.0 + 1e-9, "{:?} at {:?}", q, st);
        }
        let hull = convex_hull(&points);
        let (min, _) = brute_force_parallelogram(&hull, 0.0);
        prop_assert!(p.area() <= min * (1.0 + NEAR_MINIMAL_REL) * (1.0 + 1e-12), "{} vs optimum {}", p.area(), min);
        prop_assert!(p.area() >= min * (1.0 - 1e-9), "{} below the optimum {}", p.area(), min);
        // Angle: at least as square as every candidate safely inside the 0.1% band.
        let (_, best_sin) = brute_force_parallelogram(&hull, NEAR_MINIMAL_REL * (1.0 - 1e-6));
        let sin = p.u.normalize().perp_dot(p.v.normalize()).abs();
        prop_assert!(sin >= best_sin - 1e-9, "|sin| {} but a near-minimal candidate has {}", sin, best_sin);
    }
}

/// World-space distance from `x` to the closed polygon (boundary segments; 0 inside).
fn world_distance_to_face(rings: &[Vec<DVec2>], x: DVec2) -> f64 {
    if twin_locate(rings, x) != Location::Outside {
        return 0.0;
    }
    let mut best = f64::INFINITY;
    for ring in rings {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let t = ((x - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            best = best.min(x.distance(a + (b - a) * t));
        }
    }
    best
}

proptest! {
    #![proptest_config(config(300, 0x0c10_5e57))]

    /// Closest point: on the face, at the brute-force distance, and no sampled face point is closer.
    #[test]
    fn closest_point_is_on_the_face_and_nearest(
        seed in any::<u64>(), n_outer in 3usize..30, n_holes in 0usize..5
    ) {
        let Some(unit_rings) = random_polygon(seed, n_outer, n_holes, false) else { return Ok(()) };
        let mut rng = Rng::new(seed ^ 0x77);
        let affine = random_affine(&mut rng);
        let world: Vec<Vec<DVec2>> = unit_rings.iter().map(|r| r.iter().map(|p| affine(*p)).collect()).collect();
        let domain = ExtendedDomain::from_plane_polygon(&world[0], &world[1..]).expect("domain");
        prop_assert!(domain.uses_trapezoidal_map());
        // Face samples: points along every edge and contained points of a grid.
        let mut samples = Vec::new();
        for ring in domain.rings() {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                for k in 0..16 {
                    samples.push(a + (b - a) * (k as f64 / 16.0));
                }
            }
        }
        for i in 0..40 {
            for j in 0..40 {
                let st = DVec2::new(i as f64 + 0.5, j as f64 + 0.5) / 40.0;
                if domain.contains(st) {
                    samples.push(st);
                }
            }
        }
        let to_world = |st: DVec2| domain.world_point(st).truncate();
        let scale = domain.domain_area_m2().sqrt();
        for _ in 0..20 {
            let st = DVec2::new(rng.range(-0.3, 1.3), rng.range(-0.3, 1.3));
            let c = domain.closest_point_on_face(st);
            prop_assert!(c.is_finite());
            let d = to_world(st).distance(to_world(c));
            // On the face: contained, or on the boundary up to rounding.
            prop_assert!(world_distance_to_face(&world, to_world(c)) <= 1e-9 * scale);
            // As close as the exact distance computed in world space.
            let exact = world_distance_to_face(&world, to_world(st));
            prop_assert!((d - exact).abs() <= 1e-9 * scale, "{} vs {}", d, exact);
            for s in &samples {
                prop_assert!(d <= to_world(st).distance(to_world(*s)) + 1e-9 * scale);
            }
        }
    }
}

proptest! {
    #![proptest_config(config(300, 0x0cc1_0de5))]

    /// Segment-versus-face occlusion equals a brute-force plane crossing plus a point-in-polygon
    /// test in the face's own plane coordinates (points within 1e-7 of the boundary skipped).
    #[test]
    fn occlusion_matches_the_brute_force_test(
        seed in any::<u64>(), n_outer in 3usize..30, n_holes in 0usize..5
    ) {
        let Some(rings) = random_polygon(seed, n_outer, n_holes, false) else { return Ok(()) };
        let mut rng = Rng::new(seed ^ 0x99);
        // A random plane: an orthonormal basis (e1, e2, n) and an origin.
        let n = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or(DVec3::Z);
        let (e1, e2) = n.any_orthonormal_pair();
        let o = DVec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
        let scale = rng.range(0.5, 3.0);
        let lift = |p: DVec2| o + (e1 * p.x + e2 * p.y) * scale;
        let rings3: Vec<Vec<DVec3>> = rings.iter().map(|r| r.iter().map(|p| lift(*p)).collect()).collect();
        let domain = ExtendedDomain::new(&rings3[0], &rings3[1..], n).expect("domain");
        let mut tried = 0;
        for _ in 0..60 {
            let target = lift(DVec2::new(rng.range(-0.1, 1.1), rng.range(-0.1, 1.1)));
            let dir = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            // Mostly segments through the plane at `target`, some ending short of it.
            let (a, b) = (target + dir * rng.range(-2.0, 0.2), target + dir * rng.range(-0.2, 2.0));
            // Brute force in the plane's own coordinates.
            let (da, db) = (n.dot(a - o), n.dot(b - o));
            let expected = if da * db < 0.0 {
                let x = a + (b - a) * (da / (da - db));
                let p = DVec2::new((x - o).dot(e1), (x - o).dot(e2)) / scale;
                if world_distance_to_boundary(&rings, p) < 1e-7 {
                    continue;
                }
                twin_locate(&rings, p) == Location::Inside
            } else {
                false
            };
            if da.abs() < 1e-9 || db.abs() < 1e-9 {
                continue;
            }
            tried += 1;
            prop_assert_eq!(domain.segment_hits_face(a, b), expected, "segment {:?} -> {:?}", a, b);
        }
        prop_assert!(tried > 0);
    }
}

fn world_distance_to_boundary(rings: &[Vec<DVec2>], x: DVec2) -> f64 {
    let mut best = f64::INFINITY;
    for ring in rings {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let t = ((x - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            best = best.min(x.distance(a + (b - a) * t));
        }
    }
    best
}

/// Checks a domain is usable: finite frame along the normal, fill ratio in [0, 1], and every query
/// answers without NaN.
fn assert_valid_domain(d: &ExtendedDomain) {
    let f = d.frame;
    assert!(
        f.origin.is_finite() && f.u.is_finite() && f.v.is_finite(),
        "{f:?}"
    );
    assert!(
        f.cross().dot(d.normal) > 0.0,
        "u x v must point along the normal: {f:?}"
    );
    assert!(d.domain_area_m2() > 0.0 && d.domain_area_m2().is_finite());
    let fill = d.fill_ratio();
    assert!((0.0..=1.0).contains(&fill), "fill ratio {fill}");
    for ring in d.rings() {
        for p in ring {
            assert!(
                p.min_element() >= 0.0 && p.max_element() <= 1.0,
                "vertex {p} outside [0,1]^2"
            );
        }
    }
    for i in 0..=8 {
        for j in 0..=8 {
            let st = DVec2::new(i as f64, j as f64) / 8.0 * 1.2 - DVec2::splat(0.1);
            let _ = d.contains(st);
            assert!(d.closest_point_on_face(st).is_finite());
            let c = d.coverage(StBox::new(st, st + DVec2::splat(0.15)));
            assert!(c.area.is_finite() && c.area >= 0.0);
        }
    }
    let _ = d.segment_hits_face(
        d.world_point(DVec2::splat(0.5)) + d.normal,
        d.world_point(DVec2::splat(0.5)) - d.normal,
    );
}

#[test]
fn degenerate_faces_give_valid_domains() {
    let p = |x: f64, y: f64| DVec2::new(x, y);
    let cases: Vec<(&str, Vec<DVec2>)> = vec![
        (
            "collinear",
            vec![p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0), p(3.0, 3.0)],
        ),
        (
            "collinear folded",
            vec![p(0.0, 0.0), p(2.0, 0.0), p(1.0, 0.0)],
        ),
        (
            "repeated vertices",
            vec![
                p(0.0, 0.0),
                p(0.0, 0.0),
                p(1.0, 0.0),
                p(1.0, 0.0),
                p(0.0, 1.0),
                p(0.0, 0.0),
            ],
        ),
        ("single point", vec![p(3.0, 4.0), p(3.0, 4.0), p(3.0, 4.0)]),
        ("two points", vec![p(3.0, 4.0), p(5.0, 4.0)]),
        ("empty", vec![]),
        ("triangle", vec![p(0.0, 0.0), p(2.0, 0.0), p(0.5, 1.0)]),
        (
            "rectangle",
            vec![p(0.0, 0.0), p(3.0, 0.0), p(3.0, 1.0), p(0.0, 1.0)],
        ),
        (
            "sliver",
            vec![p(0.0, 0.0), p(10.0, 0.0), p(10.0, 1e-7), p(5.0, 2e-7)],
        ),
        (
            "clockwise",
            vec![p(0.0, 0.0), p(0.0, 1.0), p(1.0, 1.0), p(1.0, 0.0)],
        ),
        (
            "far from origin",
            vec![
                p(1e6, 1e6),
                p(1e6 + 1.0, 1e6),
                p(1e6 + 0.5, 1e6 + 2.0),
                p(1e6, 1e6 + 1.0),
            ],
        ),
    ];
    for (name, outer) in cases {
        let d = ExtendedDomain::from_plane_polygon(&outer, &[])
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_valid_domain(&d);
        let fill = d.fill_ratio();
        match name {
            "triangle" | "repeated vertices" => {
                assert!((fill - 0.5).abs() < 1e-12, "{name}: fill {fill}")
            }
            "rectangle" | "clockwise" => assert!((fill - 1.0).abs() < 1e-12, "{name}: fill {fill}"),
            "collinear" | "collinear folded" | "single point" | "two points" | "empty" => {
                assert_eq!(fill, 0.0, "{name}");
                assert!(!d.contains(DVec2::splat(0.5)), "{name}");
            }
            _ => {}
        }
    }
    // A rectangle's domain is the rectangle itself.
    let d = ExtendedDomain::from_plane_polygon(
        &[p(0.0, 0.0), p(3.0, 0.0), p(3.0, 1.0), p(0.0, 1.0)],
        &[],
    )
    .expect("rectangle");
    assert!((d.domain_area_m2() - 3.0).abs() < 1e-12);
    assert!(d.frame.u.dot(d.frame.v).abs() < 1e-12);
    // A hole that is only a line is dropped; a hole touching the outer ring at a vertex is kept.
    let outer = [p(0.0, 0.0), p(4.0, 0.0), p(4.0, 4.0), p(0.0, 4.0)];
    let d =
        ExtendedDomain::from_plane_polygon(&outer, &[vec![p(1.0, 1.0), p(2.0, 2.0), p(3.0, 3.0)]])
            .expect("line hole");
    assert_eq!(d.rings().len(), 1);
    let touching = vec![p(0.0, 0.0), p(1.0, 2.0), p(2.0, 1.0)];
    let d = ExtendedDomain::from_plane_polygon(&outer, &[touching]).expect("touching hole");
    assert!(d.uses_trapezoidal_map(), "{:?}", d.map_error());
    assert_valid_domain(&d);
    assert!((d.fill_ratio() - (16.0 - 1.5) / 16.0).abs() < 1e-12);
    // Non-finite input is refused, not a panic.
    assert!(
        ExtendedDomain::from_plane_polygon(&[p(0.0, 0.0), p(f64::NAN, 0.0), p(0.0, 1.0)], &[])
            .is_err()
    );
    assert!(ExtendedDomain::new(&[DVec3::ZERO, DVec3::X, DVec3::Y], &[], DVec3::ZERO).is_err());
}

#[test]
fn crossing_rings_fall_back_to_winding_numbers() {
    // A bow tie: its edges cross, so the map refuses it and point location uses the rings.
    let ring = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(1.0, 1.0),
        DVec2::new(1.0, 0.0),
        DVec2::new(0.0, 1.0),
    ];
    assert!(TrapezoidalMap::new(std::slice::from_ref(&ring)).is_err());
    let d = ExtendedDomain::from_plane_polygon(&ring, &[]).expect("bow tie");
    assert!(!d.uses_trapezoidal_map());
    assert_valid_domain(&d);
}

#[test]
fn map_of_a_comb_with_shared_x_coordinates() {
    // Vertical edges and many vertices on one x: the lexicographic order's degenerate cases.
    let mut ring = vec![DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0)];
    for i in (0..10).rev() {
        let x = i as f64;
        ring.push(DVec2::new(x + 1.0, 3.0));
        ring.push(DVec2::new(x + 0.5, 3.0));
        ring.push(DVec2::new(x + 0.5, 1.0));
        ring.push(DVec2::new(x, 1.0));
    }
    let rings = vec![ring];
    assert!(is_valid_polygon(&rings));
    let map = TrapezoidalMap::new_checked(&rings).expect("comb");
    for i in 0..=44 {
        for j in 0..=16 {
            let p = DVec2::new(i as f64 * 0.25 - 0.5, j as f64 * 0.25 - 0.5);
            assert_eq!(map.locate(p), twin_locate(&rings, p), "{p}");
        }
    }
}

/// The scenes of `../shared/scenes` (absent in a fresh clone: the test then skips).
fn shared_scenes() -> Vec<std::path::PathBuf> {
    crate::scene::scene_files(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"),
    )
}

/// On every real extended face: a domain framing its surfaces, the trapezoidal map built (no
/// fallback) and agreeing with the winding twin, vertices enclosed, areas consistent.
#[test]
fn every_extended_face_of_the_shared_scenes_gets_a_mapped_domain() {
    use crate::domain::{build_domains, DomainMode};
    use crate::faces::{merge_planar_faces, FaceKind};
    let paths = shared_scenes();
    if paths.is_empty() {
        println!("SKIP: no ../shared/scenes");
        return;
    }
    let mut extended_faces = 0;
    for path in paths {
        let name = path.display().to_string();
        let scene = crate::scene::load_scene_from_path(&path, 5_000_000)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let faces = merge_planar_faces(&scene);
        let domains = build_domains(&scene, &faces, DomainMode::Extended);
        assert_eq!(domains.extended.len(), faces.faces.len());
        for face in &faces.faces {
            let d = &domains.extended[face.id.0 as usize];
            if face.kind != FaceKind::Extended {
                assert!(d.is_none());
                continue;
            }
            extended_faces += 1;
            let id = face.id.0;
            let d = d
                .as_ref()
                .unwrap_or_else(|| panic!("{name}: face {id} has no domain"));
            assert!(
                d.uses_trapezoidal_map(),
                "{name}: face {id}: {:?}",
                d.map_error()
            );
            for s in domains.surfaces.iter().filter(|s| s.face == face.id) {
                let (u, v) = match s.side {
                    crate::domain::Side::Front => (s.frame.u, s.frame.v),
                    crate::domain::Side::Back => (s.frame.v, s.frame.u),
                };
                assert_eq!(
                    (s.frame.origin, u, v),
                    (d.frame.origin, d.frame.u, d.frame.v)
                );
                let fill = s.fill_ratio();
                assert!(
                    fill > 0.0 && fill <= 1.0 + 1e-9,
                    "{name}: face {id}: fill {fill}"
                );
            }
            let scale = d.domain_area_m2().sqrt();
            for p in face.outer.iter().chain(face.holes.iter().flatten()) {
                let st = d.coordinates(*p);
                assert!(
                    st.min_element() >= -1e-9 && st.max_element() <= 1.0 + 1e-9,
                    "{name}: face {id}: vertex at {st}"
                );
                // Corners lie within twice the face tolerance of the face's plane.
                let off = d.world_point(st).distance(*p);
                assert!(
                    off <= 2.0 * faces.tolerance_m + 1e-9 * scale,
                    "{name}: face {id}: vertex {off} m off its domain"
                );
            }
            let perimeter: f64 = std::iter::once(&face.outer)
                .chain(&face.holes)
                .map(|r| {
                    (0..r.len())
                        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
                        .sum::<f64>()
                })
                .sum();
            assert!(
                (d.face_area_m2() - face.area_m2).abs()
                    <= faces.tolerance_m * perimeter + 1e-9 * face.area_m2,
                "{name}: face {id}: rings {} m^2, triangles {} m^2",
                d.face_area_m2(),
                face.area_m2
            );
            // The whole domain's coverage is the face; the map agrees with the twin at the
            // centroids of the face's triangles (inside, unless rounding puts a sliver's
            // centroid on the other side of a boundary it hugs).
            let whole = d.coverage(StBox::new(DVec2::ZERO, DVec2::ONE));
            assert!((whole.area - d.fill_ratio()).abs() <= 1e-9);
            let mut outside = 0;
            for t in &face.triangulation {
                let st = d.coordinates((t[0] + t[1] + t[2]) / 3.0);
                let loc = d.locate(st);
                assert_eq!(loc, twin_locate(d.rings(), st), "{name}: face {id} at {st}");
                outside += usize::from(loc == Location::Outside);
            }
            assert!(
                outside * 100 <= face.triangulation.len(),
                "{name}: face {id}: {outside} centroids outside"
            );
        }
    }
    assert!(extended_faces > 0);
    println!("{extended_faces} extended faces checked");
}

#[test]
fn an_empty_map_is_all_outside_and_paths_are_bounded_by_the_depth() {
    let empty = TrapezoidalMap::new(&[]).expect("empty");
    assert_eq!(
        (
            empty.segment_count(),
            empty.trapezoid_count(),
            empty.depth()
        ),
        (0, 1, 0)
    );
    assert_eq!(empty.locate(DVec2::ZERO), Location::Outside);
    let rings = random_polygon(7, 40, 4, false).expect("polygon");
    let map = TrapezoidalMap::new(&rings).expect("map");
    let edges: usize = rings.iter().map(Vec::len).sum();
    assert_eq!(map.segment_count(), edges);
    // 3n + 1 trapezoids at most (de Berg et al., lemma 6.2).
    assert!(map.trapezoid_count() <= 3 * edges + 1);
    let mut rng = Rng::new(3);
    for p in query_points(&mut rng, &rings, 200) {
        let len = map.search_path_length(p);
        assert!(len >= 1 && len <= map.depth(), "{len} > {}", map.depth());
    }
    assert!(map.build_steps() >= edges as u64);
}

/// Large maps have deep DAGs (the van Emde Boas layout recurses several levels): they still
/// locate like the twin, and the construction's counts add up.
#[test]
fn large_maps_locate_like_the_twin_and_count_their_work() {
    for (seed, n_outer, n_holes, snap) in [(21, 3000, 0, false), (22, 1500, 4, true)] {
        let Some(rings) = random_polygon(seed, n_outer, n_holes, snap) else {
            continue;
        };
        let map = TrapezoidalMap::new_checked(&rings).expect("map");
        let stats = map.build_stats();
        assert_eq!(stats.segments as usize, map.segment_count());
        assert_eq!(
            stats.created_trapezoids - stats.destroyed_trapezoids,
            map.trapezoid_count() as u64
        );
        assert!(stats.located_nodes >= stats.segments);
        assert_eq!(map.build_steps(), stats.steps());
        assert!(map.node_count() <= 8 * map.segment_count());
        assert!(map.depth() > 20, "depth {}", map.depth());
        let mut rng = Rng::new(seed);
        for p in query_points(&mut rng, &rings, 1500) {
            assert_eq!(map.locate(p), twin_locate(&rings, p), "point {p:?}");
            assert!(map.search_path_length(p) <= map.depth());
        }
    }
}

#[test]
fn extreme_slivers_give_valid_domains() {
    // Width over length down to 1e-14: (s, t) of the vertices carry rounding errors far above
    // 1e-9 of the domain's width; they are clamped, never a panic or NaN.
    for k in [4, 8, 11, 14] {
        let h = 10f64.powi(-k);
        let outer = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.7, h),
            DVec2::new(0.2, 0.9 * h),
        ];
        let d = ExtendedDomain::from_plane_polygon(&outer, &[]).expect("sliver");
        assert_valid_domain(&d);
        assert!(d.fill_ratio() > 0.5, "1e-{k}: fill {}", d.fill_ratio());
    }
}

#[test]
fn maps_are_reproducible() {
    let rings = random_polygon(11, 40, 3, true).expect("polygon");
    let (a, b) = (
        TrapezoidalMap::new(&rings).expect("a"),
        TrapezoidalMap::new(&rings).expect("b"),
    );
    assert_eq!(
        (a.depth(), a.build_steps(), a.trapezoid_count()),
        (b.depth(), b.build_steps(), b.trapezoid_count())
    );
}

proptest! {
    #![proptest_config(config(1500, 0xf022_0001))]

    /// Arbitrary rings (self-intersecting, overlapping, touching, on a coarse grid so degenerate
    /// contacts are common): the map either refuses them or answers exactly like the
    /// nonzero-winding twin; valid polygons are never refused; nothing panics.
    #[test]
    fn map_refuses_or_answers_right_on_arbitrary_rings(
        seed in any::<u64>(), n_rings in 1usize..4, n in 3usize..9, grid in 2.0f64..9.0
    ) {
        let mut rng = Rng::new(seed);
        let grid = grid.floor();
        let rings: Vec<Vec<DVec2>> = (0..n_rings)
            .map(|_| (0..n).map(|_| (DVec2::new(rng.f(), rng.f()) * grid).floor() / grid).collect())
            .collect();
        let valid = is_valid_polygon(&rings);
        match TrapezoidalMap::new_checked(&rings) {
            Ok(map) => {
                for p in query_points(&mut rng, &rings, 40) {
                    let twin = locate_by_winding(&rings, p);
                    prop_assert_eq!(map.locate(p), twin, "{:?} at {:?}", rings, p);
                }
            }
            Err(e) => prop_assert!(!valid, "a valid polygon was refused: {:?} {:?}", e, rings),
        }
        // The domain of the same rings never panics and is usable.
        if let Ok(d) = ExtendedDomain::from_plane_polygon(&rings[0], &rings[1..]) {
            assert_valid_domain(&d);
        }
    }
}

//! The face inside an extended root's parameter square: what the solver asks of an
//! [`ExtendedDomain`], in the root's own `(s, t)` (the domain's `(t, s)` on a back side).
//!
//! Owns the change of coordinates between a root side and its domain, and the one operation the
//! domain itself does not offer: [`clip_rings_to_box`], the face cut by an axis-aligned box as
//! closed rings whose signed integrals (area, moments, contour form factors) are those of the face
//! inside the box.
//!
//! Invariants: every ring [`FaceMask::clip`] returns is oriented as the face's rings are in the
//! root's coordinates (outer counter-clockwise about the side's normal, holes clockwise), so signed
//! integrals are positive for the face; coordinates a back side passes are swapped exactly (no
//! rounding), so front and back see the same face.

use super::coverage::{Coverage, StBox};
use super::extended::ExtendedDomain;
use glam::DVec2;
use std::sync::Arc;

/// How far inside the face (relative to the scene's diagonal) the stand-in of a domain point
/// outside the face sits: ten times the visibility's endpoint tolerance (`1e-6` of the diagonal),
/// so a ray from it towards a wall standing on the face's border hits that wall far enough from
/// its start to count.
pub const VISIBILITY_INSET_REL: f64 = 1e-5;

/// An extended face seen from one of its sides' roots.
#[derive(Debug, Clone)]
pub struct FaceMask {
    domain: Arc<ExtendedDomain>,
    /// The root is a back side: its `(s, t)` is the domain's `(t, s)`.
    swap: bool,
    /// [`Self::closest_point`] brings points this far (metres) inside the face.
    inset: f64,
}

impl FaceMask {
    /// `inset`: metres, usually `VISIBILITY_INSET_REL` times the scene's diagonal.
    pub fn new(domain: Arc<ExtendedDomain>, swap: bool, inset: f64) -> Self {
        FaceMask {
            domain,
            swap,
            inset,
        }
    }

    pub fn domain(&self) -> &ExtendedDomain {
        &self.domain
    }

    /// Swaps coordinates on a back side (an involution: the same map both ways).
    fn flip(&self, st: DVec2) -> DVec2 {
        if self.swap {
            DVec2::new(st.y, st.x)
        } else {
            st
        }
    }

    fn flip_box(&self, b: StBox) -> StBox {
        StBox::new(self.flip(b.min), self.flip(b.max))
    }

    /// The closed face contains root point `st`.
    pub fn contains(&self, st: DVec2) -> bool {
        self.domain.contains(self.flip(st))
    }

    /// The face inside the root box `b` (area in root `(s,t)` units, and the element status).
    pub fn coverage(&self, b: StBox) -> Coverage {
        self.domain.coverage(self.flip_box(b))
    }

    /// The stand-in on the face of root point `st` for visibility (`st` itself when on the face):
    /// its closest face point, brought `inset` inside the face
    /// ([`ExtendedDomain::closest_point_inset`]).
    pub fn closest_point(&self, st: DVec2) -> DVec2 {
        self.flip(self.domain.closest_point_inset(self.flip(st), self.inset))
    }

    /// Face area over domain area.
    pub fn fill_ratio(&self) -> f64 {
        self.domain.fill_ratio()
    }

    /// The face inside root box `b` as rings in root coordinates (see [`clip_rings_to_box`]),
    /// outer rings counter-clockwise in the root's coordinates.
    pub fn clip(&self, b: StBox) -> Vec<Vec<DVec2>> {
        let mut rings = clip_rings_to_box(self.domain.rings(), self.flip_box(b));
        if self.swap {
            for r in &mut rings {
                for p in r.iter_mut() {
                    *p = DVec2::new(p.y, p.x);
                }
                // Swapping the axes is a reflection: restore the orientation.
                r.reverse();
            }
        }
        rings
    }
}

/// Clips every ring to the box `b` (Sutherland-Hodgman against its four sides). A ring is clipped
/// on its own; the result may run along the box's sides, but its winding number is the ring's
/// inside the box and zero outside, so the signed integral of any function over the returned rings
/// equals its integral over the face (with holes) inside the box. Rings that vanish are dropped.
pub fn clip_rings_to_box(rings: &[Vec<DVec2>], b: StBox) -> Vec<Vec<DVec2>> {
    let mut out = Vec::new();
    let mut scratch = Vec::new();
    for ring in rings {
        // Rings entirely inside the box need no clipping; entirely outside on one side vanish.
        let (lo, hi) = ring.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        if hi.x <= b.min.x || lo.x >= b.max.x || hi.y <= b.min.y || lo.y >= b.max.y {
            continue;
        }
        let mut current = ring.clone();
        for side in 0..4 {
            scratch.clear();
            let inside = |p: DVec2| match side {
                0 => p.x >= b.min.x,
                1 => p.x <= b.max.x,
                2 => p.y >= b.min.y,
                _ => p.y <= b.max.y,
            };
            let cut = |p: DVec2, q: DVec2| -> DVec2 {
                // The crossing of segment p-q with the side's line, the side's coordinate set exactly.
                let (axis_value, along_x) = match side {
                    0 => (b.min.x, true),
                    1 => (b.max.x, true),
                    2 => (b.min.y, false),
                    _ => (b.max.y, false),
                };
                if along_x {
                    let t = (axis_value - p.x) / (q.x - p.x);
                    DVec2::new(axis_value, p.y + (q.y - p.y) * t)
                } else {
                    let t = (axis_value - p.y) / (q.y - p.y);
                    DVec2::new(p.x + (q.x - p.x) * t, axis_value)
                }
            };
            let n = current.len();
            for i in 0..n {
                let (p, q) = (current[i], current[(i + 1) % n]);
                let (ip, iq) = (inside(p), inside(q));
                if ip {
                    scratch.push(p);
                }
                if ip != iq {
                    scratch.push(cut(p, q));
                }
            }
            std::mem::swap(&mut current, &mut scratch);
            if current.len() < 3 {
                break;
            }
        }
        if current.len() >= 3 {
            out.push(current);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::coverage::box_coverage;
    use crate::domain::extended::locate_by_winding;
    use crate::domain::predicates::signed_area;
    use crate::domain::Location;
    use proptest::prelude::*;

    fn square_with_hole() -> Vec<Vec<DVec2>> {
        let v = |x: f64, y: f64| DVec2::new(x, y);
        vec![
            vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)],
            vec![v(0.25, 0.25), v(0.25, 0.75), v(0.75, 0.75), v(0.75, 0.25)],
        ]
    }

    fn clipped_area(rings: &[Vec<DVec2>], b: StBox) -> f64 {
        clip_rings_to_box(rings, b)
            .iter()
            .map(|r| signed_area(r))
            .sum()
    }

    #[test]
    fn clipping_a_holed_square_keeps_the_area_inside_the_box() {
        let rings = square_with_hole();
        let all = StBox::new(DVec2::splat(-1.0), DVec2::splat(2.0));
        assert!((clipped_area(&rings, all) - 0.75).abs() < 1e-15);
        // The left half: 0.5 minus the hole's left half (0.25 x 0.5).
        let left = StBox::new(DVec2::ZERO, DVec2::new(0.5, 1.0));
        assert!((clipped_area(&rings, left) - (0.5 - 0.125)).abs() < 1e-15);
        // A box inside the hole: nothing.
        let hole = StBox::new(DVec2::splat(0.3), DVec2::splat(0.7));
        assert!(clipped_area(&rings, hole).abs() < 1e-15);
        // A box outside: no ring at all.
        let outside = StBox::new(DVec2::splat(1.5), DVec2::splat(2.0));
        assert!(clip_rings_to_box(&rings, outside).is_empty());
    }

    #[test]
    fn a_back_side_mask_sees_the_face_mirrored_with_its_orientation_kept() {
        let v = |x: f64, y: f64| DVec2::new(x, y);
        let outer = vec![
            v(0.0, 0.0),
            v(1.0, 0.0),
            v(1.0, 0.5),
            v(0.5, 0.5),
            v(0.5, 1.0),
            v(0.0, 1.0),
        ];
        let d = Arc::new(ExtendedDomain::from_plane_polygon(&outer, &[]).unwrap());
        let (front, back) = (
            FaceMask::new(d.clone(), false, 1e-6),
            FaceMask::new(d, true, 1e-6),
        );
        let mut inside = 0;
        for i in 0..=20 {
            for j in 0..=20 {
                let p = v(i as f64 / 20.0, j as f64 / 20.0);
                assert_eq!(front.contains(p), back.contains(v(p.y, p.x)));
                inside += front.contains(p) as usize;
                let (cf, cb) = (front.closest_point(p), back.closest_point(v(p.y, p.x)));
                assert_eq!(cf, v(cb.y, cb.x));
                assert!(front.contains(cf));
            }
        }
        assert!(
            inside > 0 && inside < 21 * 21,
            "the L shape fills part of its domain"
        );
        let bx = StBox::new(v(0.0, 0.0), v(1.0, 0.7));
        for mask in [&front, &back] {
            let area: f64 = mask.clip(bx).iter().map(|r| signed_area(r)).sum();
            let cov = mask.coverage(bx);
            assert!(
                area > 0.0 && (area - cov.area).abs() < 1e-12,
                "{area} vs {}",
                cov.area
            );
        }
    }

    /// Every point outside the face is brought inside it, at least half the inset from its
    /// boundary (world distance), at straight edges, convex and acute corners and around holes.
    #[test]
    fn stand_ins_of_outside_points_sit_inside_the_face_off_its_boundary() {
        let v = |x: f64, y: f64| DVec2::new(x, y);
        let l_with_hole = (
            vec![
                v(0.0, 0.0),
                v(4.0, 0.0),
                v(4.0, 1.5),
                v(1.5, 1.5),
                v(1.5, 4.0),
                v(0.0, 4.0),
            ],
            vec![vec![v(0.5, 0.5), v(0.5, 1.0), v(1.0, 1.0), v(1.0, 0.5)]],
        );
        // A pentagon with a 20-degree corner at the origin.
        let a = 20f64.to_radians();
        let acute = (
            vec![
                v(0.0, 0.0),
                v(4.0, 0.0),
                v(4.0, 1.0),
                v(4.0 * a.cos(), 4.0 * a.sin()),
                v(2.0 * a.cos(), 2.0 * a.sin()),
            ],
            vec![],
        );
        let inset = 0.01;
        for (shape, (outer, holes)) in [l_with_hole, acute].into_iter().enumerate() {
            let d = ExtendedDomain::from_plane_polygon(&outer, &holes).unwrap();
            let world = |st: DVec2| d.world_point(st);
            let boundary_distance = |st: DVec2| {
                let x = world(st);
                d.rings()
                    .iter()
                    .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
                    .map(|(p, q)| {
                        let (p, q) = (world(p), world(q));
                        let t = ((x - p).dot(q - p) / (q - p).length_squared()).clamp(0.0, 1.0);
                        (p + (q - p) * t - x).length()
                    })
                    .fold(f64::INFINITY, f64::min)
            };
            let mut moved = 0;
            for i in 0..=40 {
                for j in 0..=40 {
                    let st = v(i as f64 / 40.0, j as f64 / 40.0);
                    if d.contains(st) {
                        assert_eq!(d.closest_point_inset(st, inset), st);
                        continue;
                    }
                    let p = d.closest_point_inset(st, inset);
                    assert!(
                        d.contains(p),
                        "shape {shape}: {st} -> {p} is not in the face"
                    );
                    let dist = boundary_distance(p);
                    assert!(
                        dist >= 0.5 * inset,
                        "shape {shape}: {st} -> {p}: {dist} from the boundary"
                    );
                    moved += 1;
                }
            }
            assert!(moved > 100);
        }
    }

    /// A random star-shaped ring around `c` (simple by construction), counter-clockwise.
    fn star(c: DVec2, radii: &[f64], scale: f64) -> Vec<DVec2> {
        let n = radii.len();
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                c + DVec2::new(a.cos(), a.sin()) * radii[i] * scale
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
        /// The clipped rings' area equals the exact coverage (an independent method: swept areas),
        /// and a point inside the box is in the clipped rings exactly when it is in the face.
        #[test]
        fn clipped_area_matches_coverage(
            outer in prop::collection::vec(0.5f64..1.0, 3..12),
            hole in prop::collection::vec(0.3f64..1.0, 3..8),
            lo in (0.0f64..1.0, 0.0f64..1.0),
            ext in (0.01f64..1.0, 0.01f64..1.0),
            probe in (0.0f64..1.0, 0.0f64..1.0),
        ) {
            let c = DVec2::splat(0.5);
            let mut h = star(c, &hole, 0.2);
            h.reverse();
            let rings = vec![star(c, &outer, 0.5), h];
            let b = StBox::new(DVec2::new(lo.0, lo.1), DVec2::new(lo.0 + ext.0, lo.1 + ext.1));
            let cov = box_coverage(&rings, b, |p| locate_by_winding(&rings, p) != Location::Outside);
            let clipped = clip_rings_to_box(&rings, b);
            let area: f64 = clipped.iter().map(|r| signed_area(r)).sum();
            prop_assert!((area - cov.area).abs() < 1e-12, "{area} vs {}", cov.area);
            let p = b.min + (b.max - b.min) * DVec2::new(probe.0, probe.1);
            let winding = |rs: &[Vec<DVec2>]| rs.iter().map(|r| winding_number(r, p)).sum::<i32>();
            let on_boundary = rings.iter().chain(clipped.iter()).any(|r| near_ring(r, p));
            if !on_boundary {
                prop_assert_eq!(winding(&clipped), winding(&rings));
            }
        }
    }

    fn winding_number(ring: &[DVec2], p: DVec2) -> i32 {
        let n = ring.len();
        let mut w = 0;
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let side = (b - a).perp_dot(p - a);
            if a.y <= p.y && b.y > p.y && side > 0.0 {
                w += 1;
            } else if a.y > p.y && b.y <= p.y && side < 0.0 {
                w -= 1;
            }
        }
        w
    }

    fn near_ring(ring: &[DVec2], p: DVec2) -> bool {
        let n = ring.len();
        (0..n).any(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_squared().max(1e-300)).clamp(0.0, 1.0);
            (a + ab * t - p).length() < 1e-9
        })
    }
}

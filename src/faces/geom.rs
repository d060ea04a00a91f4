//! Plane geometry shared by the face builder, the validator and the triangulator, and the crate's
//! one copy of the exact 2D predicates ([`orient`], [`on_segment`], [`signed_area`],
//! [`locate_by_winding`]), which the domain's `predicates` re-exports (faces sit below the
//! domain, so the domain uses them, never the other way).
//!
//! Owns [`Projection`], the map from a face's plane to 2D that drops the normal's dominant axis.
//! It copies two coordinates unchanged (no rounding), so the exact orientation predicate
//! ([`orient`], Shewchuk's `orient2d` from the `robust` crate) decides turns, crossings and
//! point-in-ring questions exactly for the projected points. Invariant: a ring counter-clockwise
//! about a normal `n` is counter-clockwise in `Projection::for_normal(n)` (positive [`signed_area`]);
//! projected areas are true areas times [`Projection::area_scale`] (`|n_axis|`, for a unit `n`).
//! Units: metres and square metres, like the scene. Also owns [`FastMap`]/[`FastSet`], hash
//! containers with a cheap hasher for the integer keys of the face builder (vertex ids, grid
//! cells, coordinate bits), since the standard SipHash dominated merge time.

use glam::{DVec2, DVec3};
use std::hash::{BuildHasherDefault, Hasher};

/// Multiply-rotate hasher for integer keys, with a final avalanche so that keys whose low bits are
/// all zero (f32 coordinates widened to f64) still spread over the table. Not DoS-resistant: keys
/// come from geometry, and a bad case costs time, never correctness.
#[derive(Debug, Default, Clone, Copy)]
pub struct FastHasher(u64);

impl Hasher for FastHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(u64::from(x));
    }
    fn write_i64(&mut self, x: i64) {
        self.write_u64(x as u64);
    }
    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }
    fn finish(&self) -> u64 {
        // MurmurHash3's 64-bit finaliser.
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^ (h >> 33)
    }
}

/// A `HashMap` with [`FastHasher`].
pub type FastMap<K, V> = std::collections::HashMap<K, V, BuildHasherDefault<FastHasher>>;
/// A `HashSet` with [`FastHasher`].
pub type FastSet<K> = std::collections::HashSet<K, BuildHasherDefault<FastHasher>>;

/// Orthogonal projection onto the coordinate plane most nearly parallel to a face's plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Projection {
    /// The dropped axis (0 = x, 1 = y, 2 = z).
    axis: usize,
    /// The two kept coordinates are swapped so that orientation about the normal is preserved.
    flip: bool,
}

impl Projection {
    /// The projection for a plane with normal `n` (any length; the largest component is dropped).
    pub fn for_normal(n: DVec3) -> Self {
        let a = n.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        Projection {
            axis,
            flip: n[axis] < 0.0,
        }
    }

    /// The projected point: the two kept coordinates, copied exactly.
    pub fn apply(&self, p: DVec3) -> DVec2 {
        // Cyclic order (x->y->z) keeps e_u x e_v = +e_axis.
        let (u, v) = match self.axis {
            0 => (p.y, p.z),
            1 => (p.z, p.x),
            _ => (p.x, p.y),
        };
        if self.flip {
            DVec2::new(v, u)
        } else {
            DVec2::new(u, v)
        }
    }

    /// The point of the plane `normal . p = offset` whose projection is `q` (the inverse of
    /// [`Projection::apply`] on that plane; this projection must be the plane's, or one whose
    /// dropped axis the normal is not perpendicular to).
    pub fn lift(&self, q: DVec2, normal: DVec3, offset: f64) -> DVec3 {
        let (u, v) = if self.flip { (q.y, q.x) } else { (q.x, q.y) };
        let mut p = DVec3::ZERO;
        let (iu, iv) = match self.axis {
            0 => (1, 2),
            1 => (2, 0),
            _ => (0, 1),
        };
        p[iu] = u;
        p[iv] = v;
        p[self.axis] = (offset - normal[iu] * u - normal[iv] * v) / normal[self.axis];
        p
    }

    /// Projected area / true area for a plane with unit normal `n`: `|n_axis|` (at least 1/sqrt 3).
    pub fn area_scale(&self, n: DVec3) -> f64 {
        n[self.axis].abs()
    }
}

/// Exact orientation of `c` relative to the directed line `a -> b`: positive when `a, b, c` turn
/// counter-clockwise (`c` left of / above `a -> b`), negative when clockwise, zero when collinear.
/// Only the sign is meaningful.
#[inline]
pub fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    robust::orient2d(
        robust::Coord { x: a.x, y: a.y },
        robust::Coord { x: b.x, y: b.y },
        robust::Coord { x: c.x, y: c.y },
    )
}

/// Signed area of a closed 2D ring (positive when counter-clockwise), computed about the first
/// vertex to keep far-from-origin coordinates accurate.
pub fn signed_area(ring: &[DVec2]) -> f64 {
    let Some(&o) = ring.first() else {
        return 0.0;
    };
    let mut sum = 0.0;
    for i in 1..ring.len().saturating_sub(1) {
        sum += (ring[i] - o).perp_dot(ring[i + 1] - o);
    }
    0.5 * sum
}

/// True when `p` lies on the closed segment `[a, b]` (exact).
#[inline]
pub fn on_segment(a: DVec2, b: DVec2, p: DVec2) -> bool {
    orient(a, b, p) == 0.0
        && p.x >= a.x.min(b.x)
        && p.x <= a.x.max(b.x)
        && p.y >= a.y.min(b.y)
        && p.y <= a.y.max(b.y)
}

/// Where a point is relative to closed rings (the face's point-location answer).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    Inside,
    Outside,
    /// Exactly on a ring vertex or edge.
    Boundary,
}

/// Exact point location by winding number over closed rings of either orientation (Sunday's
/// crossing rule with exact [`orient`]), the boundary first: [`Location::Boundary`] when `p` lies
/// on any ring's edge (by [`on_segment`]), else inside when the rings' total winding number is
/// non-zero. A repeated vertex (zero-length edge) is no edge, as in the domain's trapezoidal map.
/// The one point-in-polygon test of the crate: the face validator asks it about one ring, the
/// extended domain (re-exported as `extended::locate_by_winding`) about a face's rings. Pinned by
/// `locate_handles_inside_outside_and_boundary` here and the domain's property tests against an
/// even-odd twin.
pub fn locate_by_winding<R: AsRef<[DVec2]>>(rings: &[R], p: DVec2) -> Location {
    let mut winding = 0i64;
    for ring in rings {
        let ring = ring.as_ref();
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            if a == b {
                continue;
            }
            if on_segment(a, b, p) {
                return Location::Boundary;
            }
            if a.y <= p.y {
                if b.y > p.y && orient(a, b, p) > 0.0 {
                    winding += 1;
                }
            } else if b.y <= p.y && orient(a, b, p) < 0.0 {
                winding -= 1;
            }
        }
    }
    if winding != 0 {
        Location::Inside
    } else {
        Location::Outside
    }
}

/// Distance from `p` to the line through `a` and `b` (to `a` when they coincide), in 3D.
pub fn distance_to_line(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    let d = b - a;
    let len2 = d.length_squared();
    if len2 == 0.0 {
        return (p - a).length();
    }
    let t = (p - a).dot(d) / len2;
    (p - (a + d * t)).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_keeps_counter_clockwise_rings_counter_clockwise() {
        let ring = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0)];
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::new(0.3, -0.2, 0.9).normalize(),
        ] {
            // Build a frame whose third axis is n and map the ring into it.
            let u = n.any_orthonormal_vector();
            let v = n.cross(u);
            let pts: Vec<DVec3> = ring.iter().map(|p| u * p.x + v * p.y).collect();
            let proj = Projection::for_normal(n);
            let flat: Vec<DVec2> = pts.iter().map(|&p| proj.apply(p)).collect();
            let area = signed_area(&flat);
            assert!(area > 0.0, "normal {n}: {area}");
            assert!((area - 0.5 * proj.area_scale(n)).abs() < 1e-12);
            // Lifting a projected point back onto the plane gives the point.
            let offset = n.dot(pts[0]) + 0.25;
            for &p in &pts {
                let p = p + n * 0.25;
                assert!(proj.lift(proj.apply(p), n, offset).distance(p) < 1e-12);
            }
        }
    }

    #[test]
    fn locate_handles_inside_outside_and_boundary() {
        let sq = [
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
        ];
        let locate = |p: DVec2, ring: &[DVec2]| locate_by_winding(&[ring], p);
        assert_eq!(locate(DVec2::new(1.0, 1.0), &sq), Location::Inside);
        assert_eq!(locate(DVec2::new(3.0, 1.0), &sq), Location::Outside);
        assert_eq!(locate(DVec2::new(2.0, 1.0), &sq), Location::Boundary);
        assert_eq!(locate(DVec2::new(0.0, 0.0), &sq), Location::Boundary);
        let rev: Vec<DVec2> = sq.iter().rev().copied().collect();
        assert_eq!(locate(DVec2::new(1.0, 1.0), &rev), Location::Inside);
    }
}

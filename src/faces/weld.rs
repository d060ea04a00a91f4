//! Vertex welding: one id per position, within a length tolerance.
//!
//! Owns [`weld`]. Every triangle corner gets the id of a representative position; a corner takes
//! the first representative (in scene order) within `tolerance_m`, or becomes a new one.
//! Invariants: distinct representatives are more than `tolerance_m` apart; every corner is within
//! `tolerance_m` of its representative; the result depends only on the order of the triangles.
//! Exact duplicates (the common case in exports) are found by hashing their bits first; only
//! new positions search the grid (cells of `4 * tolerance_m`, so at most two cells per axis).

use super::geom::FastMap;
use crate::scene::Triangle;
use glam::DVec3;

/// Triangle corners as vertex ids into `positions`.
#[derive(Debug, Clone, Default)]
pub struct Welded {
    /// Representative positions (world frame, metres), exact copies of scene coordinates.
    pub positions: Vec<DVec3>,
    /// Per scene triangle, the ids of its three corners.
    pub corners: Vec<[u32; 3]>,
}

type Cell = (i64, i64, i64);

/// End of a cell's chain.
const END: u32 = u32::MAX;

fn cell_of(p: DVec3, inv: f64) -> Cell {
    (
        (p.x * inv).floor() as i64,
        (p.y * inv).floor() as i64,
        (p.z * inv).floor() as i64,
    )
}

/// Welds the corners of `triangles` within `tolerance_m` (which must be positive and finite).
pub fn weld(triangles: &[Triangle], tolerance_m: f64) -> Welded {
    debug_assert!(tolerance_m > 0.0 && tolerance_m.is_finite());
    let inv = 1.0 / (4.0 * tolerance_m);
    let tol2 = tolerance_m * tolerance_m;
    let mut exact: FastMap<[u64; 3], u32> =
        FastMap::with_capacity_and_hasher(triangles.len(), Default::default());
    // Per cell, the last representative put there; `next_in_cell` chains the others.
    let mut grid: FastMap<Cell, u32> = FastMap::default();
    let mut next_in_cell: Vec<u32> = Vec::new();
    let mut out = Welded {
        positions: Vec::new(),
        corners: Vec::with_capacity(triangles.len()),
    };
    for t in triangles {
        let mut ids = [0u32; 3];
        for (k, &p) in t.vertices.iter().enumerate() {
            let bits = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            if let Some(&id) = exact.get(&bits) {
                ids[k] = id;
                continue;
            }
            let lo = cell_of(p - DVec3::splat(tolerance_m), inv);
            let hi = cell_of(p + DVec3::splat(tolerance_m), inv);
            let mut found = None;
            'search: for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        let mut id = grid.get(&(x, y, z)).copied().unwrap_or(END);
                        while id != END {
                            if out.positions[id as usize].distance_squared(p) <= tol2 {
                                found = Some(id);
                                break 'search;
                            }
                            id = next_in_cell[id as usize];
                        }
                    }
                }
            }
            let id = match found {
                Some(id) => id,
                None => {
                    let id = out.positions.len() as u32;
                    out.positions.push(p);
                    let head = grid.entry(cell_of(p, inv)).or_insert(END);
                    next_in_cell.push(*head);
                    *head = id;
                    id
                }
            };
            exact.insert(bits, id);
            ids[k] = id;
        }
        out.corners.push(ids);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: DVec3, b: DVec3, c: DVec3) -> Triangle {
        Triangle::numbered([a, b, c], 0, 0)
    }

    #[test]
    fn near_duplicates_weld_and_distinct_points_do_not() {
        let e = 1e-9;
        let t0 = tri(DVec3::ZERO, DVec3::X, DVec3::Y);
        let t1 = tri(
            DVec3::new(1.0 + e, 0.0, -e),
            DVec3::Y,
            DVec3::new(1.0, 1.0, 0.0),
        );
        let w = weld(&[t0, t1], 1e-6);
        assert_eq!(w.positions.len(), 4);
        assert_eq!(w.corners[1][0], w.corners[0][1]);
        assert_eq!(w.corners[1][1], w.corners[0][2]);
        // Points straddling a grid cell boundary still weld.
        let s = 4e-6;
        let t2 = tri(DVec3::splat(s - 1e-8), DVec3::X, DVec3::Y);
        let t3 = tri(DVec3::splat(s + 1e-8), DVec3::X, DVec3::Y);
        let w = weld(&[t2, t3], 1e-6);
        assert_eq!(w.corners[0][0], w.corners[1][0]);
    }
}

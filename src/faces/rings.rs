//! Rings of a group of triangles: boundary extraction, ring walking and collinear-vertex removal.
//!
//! Owns [`build_rings`]. The boundary of a group is the algebraic sum of its triangles' directed
//! sub-edges (a sub-edge and its reverse cancel), so the interior always lies on the left of a
//! boundary edge. At a vertex with several outgoing boundary edges (rings touching there) the walk
//! takes the first edge clockwise from the way back, which keeps each ring around one wedge of
//! the face; rings that still visit a vertex twice are split there. The one counter-clockwise loop
//! is the outer ring, the clockwise ones are holes.
//!
//! Invariants of a returned [`RingIds`]: no ring repeats a vertex; the outer ring has positive and
//! every hole negative signed area in the face's [`Projection`]; a vertex where rings touch is never
//! removed as collinear; each removed vertex lies within the length tolerance of the final edge
//! that replaced it. Any inconsistency is an `Err` describing it, never a panic.

use super::adjacency::Adjacency;
use super::geom::{distance_to_line, signed_area, FastMap, FastSet, Projection};
use glam::{DVec2, DVec3};

/// Rings as welded vertex ids.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RingIds {
    pub outer: Vec<u32>,
    pub holes: Vec<Vec<u32>>,
}

/// Builds the rings of the triangles `group` (which must all be live).
pub fn build_rings(
    group: &[u32],
    corners: &[[u32; 3]],
    adj: &Adjacency,
    positions: &[DVec3],
    proj: Projection,
    tolerance_m: f64,
    simplify: bool,
) -> Result<RingIds, String> {
    let at = |v: u32| proj.apply(positions[v as usize]);

    // 1. Boundary: directed sub-edges that do not cancel.
    let mut signed: Vec<(u32, u32, i32)> = Vec::with_capacity(3 * group.len());
    for &t in group {
        let c = &corners[t as usize];
        for k in 0..3 {
            let chain = adj
                .chain(t, k, c)
                .ok_or_else(|| format!("triangle {t} has no edges"))?;
            let mut prev: Option<u32> = None;
            for v in chain {
                if let Some(u) = prev {
                    signed.push((u.min(v), u.max(v), if u < v { 1 } else { -1 }));
                }
                prev = Some(v);
            }
        }
    }
    signed.sort_unstable();
    let mut boundary: Vec<(u32, u32)> = Vec::new();
    let mut i = 0;
    while i < signed.len() {
        let (lo, hi) = (signed[i].0, signed[i].1);
        let mut net = 0;
        while i < signed.len() && signed[i].0 == lo && signed[i].1 == hi {
            net += signed[i].2;
            i += 1;
        }
        match net {
            0 => {}
            1 => boundary.push((lo, hi)),
            -1 => boundary.push((hi, lo)),
            _ => {
                return Err(format!(
                    "edge {lo}-{hi} is covered {net} times in one direction"
                ))
            }
        }
    }
    if boundary.is_empty() {
        return Err("the group has no boundary".into());
    }

    // 2. Walk the rings.
    boundary.sort_unstable();
    let out_of = |v: u32| {
        let s = boundary.partition_point(|e| e.0 < v);
        let e = boundary.partition_point(|e| e.0 <= v);
        s..e
    };
    let mut pinch: FastSet<u32> = FastSet::default();
    let mut used = vec![false; boundary.len()];
    let mut walks: Vec<Vec<u32>> = Vec::new();
    for e0 in 0..boundary.len() {
        if used[e0] {
            continue;
        }
        let mut walk = Vec::new();
        let mut e = e0;
        loop {
            used[e] = true;
            let (u, v) = boundary[e];
            walk.push(u);
            let outs = out_of(v);
            let next = match outs.len() {
                0 => return Err(format!("boundary ends at vertex {v}")),
                1 => outs.start,
                _ => {
                    pinch.insert(v);
                    // First outgoing edge clockwise from the way back to u.
                    let pv = at(v);
                    let back = (at(u) - pv).to_angle();
                    let mut best = (f64::INFINITY, outs.start);
                    for o in outs {
                        let turn = (back - (at(boundary[o].1) - pv).to_angle())
                            .rem_euclid(std::f64::consts::TAU);
                        let turn = if turn == 0.0 {
                            std::f64::consts::TAU
                        } else {
                            turn
                        };
                        if turn < best.0 {
                            best = (turn, o);
                        }
                    }
                    best.1
                }
            };
            if next == e0 {
                break;
            }
            if used[next] || walk.len() > boundary.len() {
                return Err(format!("the boundary walk at vertex {v} is inconsistent"));
            }
            e = next;
        }
        walks.push(walk);
    }

    // 3. Split walks at repeated vertices into loops.
    let mut loops: Vec<Vec<u32>> = Vec::new();
    for walk in walks {
        let mut stack: Vec<u32> = Vec::with_capacity(walk.len());
        let mut index: FastMap<u32, usize> = FastMap::default();
        for v in walk {
            if let Some(&j) = index.get(&v) {
                for &w in &stack[j + 1..] {
                    index.remove(&w);
                }
                let mut lp = stack.split_off(j + 1);
                lp.insert(0, v);
                loops.push(lp);
            } else {
                index.insert(v, stack.len());
                stack.push(v);
            }
        }
        loops.push(stack);
    }

    // 4. Orientation: one counter-clockwise loop (outer), the others clockwise (holes).
    let mut outer = None;
    let mut holes = Vec::new();
    for lp in loops {
        if lp.len() < 3 {
            return Err(format!("a ring has {} vertices", lp.len()));
        }
        let pts: Vec<DVec2> = lp.iter().map(|&v| at(v)).collect();
        let area = signed_area(&pts);
        let lp = if simplify {
            simplify_ring(&lp, &pinch, positions, proj, tolerance_m)
        } else {
            lp
        };
        let pts: Vec<DVec2> = lp.iter().map(|&v| at(v)).collect();
        let simplified = signed_area(&pts);
        if area == 0.0 || simplified == 0.0 || (area > 0.0) != (simplified > 0.0) {
            return Err("a ring has zero area".into());
        }
        if area > 0.0 {
            if outer.is_some() {
                return Err("the group has more than one outer ring".into());
            }
            outer = Some(lp);
        } else {
            holes.push(lp);
        }
    }
    let outer = outer.ok_or("the group has no outer ring")?;
    Ok(RingIds { outer, holes })
}

/// Removes the vertices of `ring` lying within `tolerance_m` of the straight edge that replaces
/// them (and between its ends), never a `keep` vertex, never below 3 vertices.
fn simplify_ring(
    ring: &[u32],
    keep: &FastSet<u32>,
    positions: &[DVec3],
    proj: Projection,
    tolerance_m: f64,
) -> Vec<u32> {
    let n = ring.len();
    if n <= 3 {
        return ring.to_vec();
    }
    // Start at the lexicographically smallest projected vertex: never strictly between its
    // neighbours, so it is a corner and the wrap-around needs no special case.
    let key = |v: u32| {
        let p = proj.apply(positions[v as usize]);
        (p.x, p.y)
    };
    let mut start = 0;
    for i in 1..n {
        let (a, b) = (key(ring[i]), key(ring[start]));
        if a.0 < b.0 || (a.0 == b.0 && a.1 < b.1) {
            start = i;
        }
    }
    let pos = |v: u32| positions[v as usize];
    let fits = |a: u32, b: u32, x: u32| {
        let (pa, pb, px) = (pos(a), pos(b), pos(x));
        let d = pb - pa;
        let t = (px - pa).dot(d) / d.length_squared();
        t > 0.0 && t < 1.0 && distance_to_line(pa, pb, px) <= tolerance_m
    };
    // kept[i] with the vertices removed between kept[i - 1] and kept[i].
    let mut kept: Vec<(u32, Vec<u32>)> = vec![(ring[start], Vec::new())];
    for i in 1..=n {
        let w = ring[(start + i) % n];
        let mut pending: Vec<u32> = Vec::new();
        while kept.len() >= 2 {
            let (top, ref before) = kept[kept.len() - 1];
            let prev = kept[kept.len() - 2].0;
            if keep.contains(&top)
                || !fits(prev, w, top)
                || !before.iter().chain(&pending).all(|&x| fits(prev, w, x))
            {
                break;
            }
            let (top, mut removed) = kept.pop().unwrap_or((top, Vec::new()));
            removed.push(top);
            removed.append(&mut pending);
            pending = removed;
        }
        kept.push((w, pending));
    }
    // The last entry is the start vertex again.
    kept.pop();
    if kept.len() < 3 {
        return ring.to_vec();
    }
    kept.into_iter().map(|k| k.0).collect()
}

//! Triangle adjacency across shared edges and T-junctions.
//!
//! Owns [`Adjacency`]. An edge used by exactly two compatible triangles, once in each direction,
//! joins them as it is (the common interior edge). Every other undirected edge of the live
//! (welded, non-degenerate) triangles is split at every welded vertex lying within the weld
//! tolerance of its interior: a T-junction, or the shared part of two collinear, overlapping
//! edges. The split is computed once per undirected edge, so the two sides of a shared edge always
//! get the same sub-edges. Two triangles are neighbours when they have a sub-edge in opposite
//! directions, are [`compatible`] (same material, same side mode, coplanar within the
//! tolerances) and neither has any other compatible triangle on that sub-edge: non-manifold and
//! duplicated edges never join faces.
//!
//! Invariants: a chain starts at its edge's lower vertex id and ends at the higher one, with its
//! interior vertices in order along the edge; `neighbours` is symmetric and has no self-loops.
//! Cost: about linear in the triangles; the T-junction search walks a vertex grid along each
//! unsettled edge (cells of half the mean edge length).

use super::geom::FastMap;
use super::weld::Welded;
use glam::DVec3;

/// What adjacency needs to know about one live triangle.
#[derive(Debug, Clone, Copy)]
pub struct TriInfo {
    /// Unit normal of the welded triangle.
    pub normal: DVec3,
    /// Plane offset: `normal . x` for points `x` of the plane.
    pub offset: f64,
    pub material: u32,
    pub double_sided: bool,
    /// Extra normal angle (radians) that corner offsets within the plane tolerance can cause on
    /// this triangle: `asin(min(1, 2 plane_m / least height))`. Thin slivers' normals are noisy.
    pub slack_rad: f64,
}

impl TriInfo {
    /// True when the normals of `self` and `other` point the same way within the angle tolerance,
    /// widened by the larger of the two triangles' slack.
    pub fn normals_agree(&self, other: &TriInfo, tol: &Tolerances) -> bool {
        let allowed =
            (tol.angle_rad + self.slack_rad.max(other.slack_rad)).min(std::f64::consts::FRAC_PI_2);
        let dot = self.normal.dot(other.normal);
        dot > 0.0 && dot >= allowed.cos()
    }
}

/// Coplanarity and side tolerances for merging.
#[derive(Debug, Clone, Copy)]
pub struct Tolerances {
    /// Length tolerance of the weld and of T-junctions (a vertex this close to an edge lies on it).
    pub length_m: f64,
    /// Largest distance of a merged triangle's corner from another's plane, metres.
    pub plane_m: f64,
    /// Largest angle between the normals of merged triangles (before slack), radians.
    pub angle_rad: f64,
}

/// Sub-edges and neighbours of the live triangles.
#[derive(Debug, Clone, Default)]
pub struct Adjacency {
    /// Per undirected edge, the start of its chain in `chains` (one past the end is the next start).
    chain_start: Vec<u32>,
    chains: Vec<u32>,
    /// Per triangle corner `3 t + k` (edge from corner k to corner k + 1): the undirected edge.
    tri_edge: Vec<u32>,
    /// Neighbours of triangle `t`: `neighbours[offsets[t]..offsets[t + 1]]`.
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    /// Number of edges split at one or more T-junction vertices.
    pub split_edges: usize,
}

/// Marks an unused slot of `tri_edge` (a dropped triangle).
const NO_EDGE: u32 = u32::MAX;

impl Adjacency {
    /// The vertex chain of edge `k` of triangle `t` (from corner k to corner k + 1), or `None` for a
    /// dropped triangle.
    pub fn chain(&self, t: u32, k: usize, corners: &[u32; 3]) -> Option<ChainIter<'_>> {
        let e = *self.tri_edge.get(3 * t as usize + k)?;
        if e == NO_EDGE {
            return None;
        }
        let s = self.chain_start[e as usize] as usize;
        let end = self.chain_start[e as usize + 1] as usize;
        let slice = &self.chains[s..end];
        let forward = slice.first() == Some(&corners[k]);
        Some(ChainIter {
            slice,
            forward,
            pos: 0,
        })
    }

    /// The neighbours of triangle `t`.
    pub fn neighbours(&self, t: u32) -> &[u32] {
        let t = t as usize;
        if t + 1 >= self.offsets.len() {
            return &[];
        }
        &self.neighbours[self.offsets[t] as usize..self.offsets[t + 1] as usize]
    }
}

/// The vertices of one triangle edge's chain, in the triangle's direction.
pub struct ChainIter<'a> {
    slice: &'a [u32],
    forward: bool,
    pos: usize,
}

impl Iterator for ChainIter<'_> {
    type Item = u32;
    fn next(&mut self) -> Option<u32> {
        if self.pos >= self.slice.len() {
            return None;
        }
        let i = if self.forward {
            self.pos
        } else {
            self.slice.len() - 1 - self.pos
        };
        self.pos += 1;
        Some(self.slice[i])
    }
}

type Cell = (i64, i64, i64);

/// A uniform grid of vertex ids; each vertex is stored in every cell its tolerance box overlaps,
/// so a segment query only needs the cells the segment itself passes through. Stored flat: the ids
/// of a cell are `ids[range.0..range.1]`.
struct VertexGrid {
    inv_cell: f64,
    cells: FastMap<Cell, (u32, u32)>,
    ids: Vec<u32>,
}

impl VertexGrid {
    fn cell(&self, p: DVec3) -> Cell {
        (
            (p.x * self.inv_cell).floor() as i64,
            (p.y * self.inv_cell).floor() as i64,
            (p.z * self.inv_cell).floor() as i64,
        )
    }

    fn new(positions: &[DVec3], used: &[bool], cell_m: f64, pad_m: f64) -> Self {
        let mut grid = VertexGrid {
            inv_cell: 1.0 / cell_m,
            cells: FastMap::default(),
            ids: Vec::new(),
        };
        let mut entries: Vec<(Cell, u32)> = Vec::with_capacity(positions.len());
        for (id, &p) in positions.iter().enumerate() {
            if !used[id] {
                continue;
            }
            let lo = grid.cell(p - DVec3::splat(pad_m));
            let hi = grid.cell(p + DVec3::splat(pad_m));
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        entries.push(((x, y, z), id as u32));
                    }
                }
            }
        }
        entries.sort_unstable();
        grid.cells.reserve(entries.len());
        grid.ids = entries.iter().map(|e| e.1).collect();
        let mut start = 0;
        while start < entries.len() {
            let mut end = start + 1;
            while end < entries.len() && entries[end].0 == entries[start].0 {
                end += 1;
            }
            grid.cells
                .insert(entries[start].0, (start as u32, end as u32));
            start = end;
        }
        grid
    }

    /// Calls `f` with every vertex stored in a cell that the segment `a b` passes through (some
    /// more than once).
    fn for_each_near_segment(&self, a: DVec3, b: DVec3, cell_m: f64, mut f: impl FnMut(u32)) {
        let d = b - a;
        let steps = ((d.abs().max_element() / cell_m).ceil() as usize).max(1);
        let eps = DVec3::splat(1e-9 * cell_m);
        for s in 0..steps {
            let p0 = a + d * (s as f64 / steps as f64);
            let p1 = a + d * ((s + 1) as f64 / steps as f64);
            let lo = self.cell(p0.min(p1) - eps);
            let hi = self.cell(p0.max(p1) + eps);
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        if let Some(&(s, e)) = self.cells.get(&(x, y, z)) {
                            self.ids[s as usize..e as usize].iter().for_each(|&v| f(v));
                        }
                    }
                }
            }
        }
    }
}

/// True when triangles `i` and `j` may share a face: same material and side mode, normals that
/// agree ([`TriInfo::normals_agree`]), and each one's corners within the plane tolerance of the
/// other's plane.
pub fn compatible(i: usize, j: usize, info: &[TriInfo], welded: &Welded, tol: &Tolerances) -> bool {
    let (a, b) = (&info[i], &info[j]);
    if a.material != b.material || a.double_sided != b.double_sided {
        return false;
    }
    if !a.normals_agree(b, tol) {
        return false;
    }
    let near = |plane: &TriInfo, t: usize| {
        welded.corners[t].iter().all(|&v| {
            (plane.normal.dot(welded.positions[v as usize]) - plane.offset).abs() <= tol.plane_m
        })
    };
    near(a, j) && near(b, i)
}

/// Builds the sub-edges and neighbours of the triangles with `live[t]`.
///
/// No two triangles join across a sub-edge lying on one of `barriers` (contact lines, see
/// `contact`): both its ends within the length tolerance of the same barrier segment.
pub fn build(
    welded: &Welded,
    live: &[bool],
    info: &[TriInfo],
    tol: &Tolerances,
    barriers: &[[DVec3; 2]],
) -> Adjacency {
    let n = welded.corners.len();
    // 1. Undirected edges.
    let mut edge_of: FastMap<(u32, u32), u32> =
        FastMap::with_capacity_and_hasher(2 * n, Default::default());
    let mut edges: Vec<(u32, u32)> = Vec::new();
    let mut tri_edge = vec![NO_EDGE; 3 * n];
    let mut used = vec![false; welded.positions.len()];
    // Per edge: (forward uses, backward uses, a forward triangle, a backward triangle).
    let mut uses: Vec<(u32, u32, u32, u32)> = Vec::new();
    for t in 0..n {
        if !live[t] {
            continue;
        }
        let c = welded.corners[t];
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let e = *edge_of.entry(key).or_insert_with(|| {
                edges.push(key);
                uses.push((0, 0, 0, 0));
                (edges.len() - 1) as u32
            });
            tri_edge[3 * t + k] = e;
            used[a as usize] = true;
            let u = &mut uses[e as usize];
            if a < b {
                u.0 += 1;
                u.2 = t as u32;
            } else {
                u.1 += 1;
                u.3 = t as u32;
            }
        }
    }
    drop(edge_of);
    // An edge shared by exactly two compatible triangles, one each way, joins them whatever lies
    // on it: only the other edges need the T-junction search.
    let settled: Vec<bool> = uses
        .iter()
        .map(|u| u.0 == 1 && u.1 == 1 && compatible(u.2 as usize, u.3 as usize, info, welded, tol))
        .collect();

    // 2. Split every edge at the vertices lying on its interior (T-junctions).
    let total_len: f64 = edges
        .iter()
        .map(|&(a, b)| welded.positions[a as usize].distance(welded.positions[b as usize]))
        .sum();
    let mean_len = if edges.is_empty() {
        1.0
    } else {
        total_len / edges.len() as f64
    };
    let cell_m = (0.5 * mean_len).max(8.0 * tol.length_m);
    let grid = VertexGrid::new(
        &welded.positions,
        &used,
        cell_m,
        tol.length_m * (1.0 + 1e-6),
    );
    let tol2 = tol.length_m * tol.length_m;
    let mut chain_start = Vec::with_capacity(edges.len() + 1);
    let mut chains = Vec::with_capacity(2 * edges.len());
    let mut found: Vec<(f64, u32)> = Vec::new();
    let mut split_edges = 0;
    for (e, &(lo, hi)) in edges.iter().enumerate() {
        if settled[e] {
            chain_start.push(chains.len() as u32);
            chains.extend([lo, hi]);
            continue;
        }
        let a = welded.positions[lo as usize];
        let b = welded.positions[hi as usize];
        let d = b - a;
        let len2 = d.length_squared();
        found.clear();
        grid.for_each_near_segment(a, b, cell_m, |v| {
            if v == lo || v == hi {
                return;
            }
            let p = welded.positions[v as usize];
            let t = (p - a).dot(d) / len2;
            if t > 0.0 && t < 1.0 && (p - (a + d * t)).length_squared() <= tol2 {
                found.push((t, v));
            }
        });
        chain_start.push(chains.len() as u32);
        chains.push(lo);
        if !found.is_empty() {
            found.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            found.dedup_by_key(|x| x.1);
            split_edges += 1;
            chains.extend(found.iter().map(|x| x.1));
        }
        chains.push(hi);
    }
    chain_start.push(chains.len() as u32);

    // Barrier segments each vertex lies on.
    let mut on_barrier: FastMap<u32, Vec<u32>> = FastMap::default();
    for (s, &[a, b]) in barriers.iter().enumerate() {
        let d = b - a;
        let len2 = d.length_squared();
        if len2 == 0.0 {
            continue;
        }
        grid.for_each_near_segment(a, b, cell_m, |v| {
            let p = welded.positions[v as usize];
            let t = ((p - a).dot(d) / len2).clamp(0.0, 1.0);
            if (p - (a + d * t)).length_squared() <= tol2 {
                let list = on_barrier.entry(v).or_default();
                if list.last() != Some(&(s as u32)) {
                    list.push(s as u32);
                }
            }
        });
    }
    let is_barrier = |u: u32, v: u32| match (on_barrier.get(&u), on_barrier.get(&v)) {
        (Some(a), Some(b)) => a.iter().any(|s| b.contains(s)),
        _ => false,
    };

    let mut adj = Adjacency {
        chain_start,
        chains,
        tri_edge,
        offsets: Vec::new(),
        neighbours: Vec::new(),
        split_edges,
    };

    // 3. Directed sub-edges, grouped by undirected sub-edge.
    let mut subs: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(3 * n);
    for t in 0..n {
        if !live[t] {
            continue;
        }
        let c = welded.corners[t];
        for k in 0..3 {
            let Some(chain) = adj.chain(t as u32, k, &c) else {
                continue;
            };
            let mut prev: Option<u32> = None;
            for v in chain {
                if let Some(u) = prev {
                    subs.push((u.min(v), u.max(v), t as u32, u < v));
                }
                prev = Some(v);
            }
        }
    }
    subs.sort_unstable();

    // 4. Match each sub-edge's triangles.
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    let mut compat: Vec<Vec<usize>> = Vec::new();
    let mut start = 0;
    while start < subs.len() {
        let mut end = start + 1;
        while end < subs.len() && subs[end].0 == subs[start].0 && subs[end].1 == subs[start].1 {
            end += 1;
        }
        let group = &subs[start..end];
        start = end;
        if group.len() < 2 || is_barrier(group[0].0, group[0].1) {
            continue;
        }
        if group.len() == 2 {
            let (x, y) = (group[0], group[1]);
            if x.3 != y.3 && x.2 != y.2 && compatible(x.2 as usize, y.2 as usize, info, welded, tol)
            {
                pairs.push((x.2, y.2));
                pairs.push((y.2, x.2));
            }
            continue;
        }
        // Non-manifold: join a pair only when each is the other's only compatible triangle.
        compat.clear();
        compat.resize(group.len(), Vec::new());
        for i in 0..group.len() {
            for j in i + 1..group.len() {
                let (ti, tj) = (group[i].2 as usize, group[j].2 as usize);
                if ti != tj && compatible(ti, tj, info, welded, tol) {
                    compat[i].push(j);
                    compat[j].push(i);
                }
            }
        }
        for i in 0..group.len() {
            if let [j] = compat[i][..] {
                if j > i && compat[j][..] == [i] && group[i].3 != group[j].3 {
                    pairs.push((group[i].2, group[j].2));
                    pairs.push((group[j].2, group[i].2));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();

    // 5. Neighbour lists (CSR).
    let mut offsets = vec![0u32; n + 1];
    for &(a, _) in &pairs {
        offsets[a as usize + 1] += 1;
    }
    for t in 0..n {
        offsets[t + 1] += offsets[t];
    }
    adj.neighbours = pairs.iter().map(|p| p.1).collect();
    adj.offsets = offsets;
    adj
}

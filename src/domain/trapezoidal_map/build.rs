//! Construction of a [`TrapezoidalMap`]: the `Builder` (trapezoids with neighbour links and a
//! search DAG whose leaves are trapezoids), randomised incremental insertion of the rings'
//! segments with the input-contract checks (crossings, overlaps, inconsistent orientation: a
//! [`MapError`], never a wrong map), `assert_well_formed` for the tests, and `freeze`, which folds
//! the leaves into inside/outside tags and lays the DAG out in van Emde Boas order. Invariant:
//! every live trapezoid's DAG leaf points back at it, and its neighbour links are mutual.

use super::{
    BuildStats, MapError, SearchNode, TrapezoidalMap, LEAF_INSIDE, LEAF_OUTSIDE, SHUFFLE_SEED,
    X_NODE,
};
use crate::domain::predicates::{lex_less, orient};
use glam::DVec2;

/// "No trapezoid / no segment / unbounded".
const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Segment {
    /// Lexicographically smaller endpoint.
    left: DVec2,
    right: DVec2,
    /// Indices of `left` and `right` in the builder's vertex list.
    left_vertex: u32,
    right_vertex: u32,
    /// The face lies above the segment (it was directed left to right in its ring).
    interior_above: bool,
}

#[derive(Debug, Clone, Copy)]
struct Trapezoid {
    /// Segments bounding it above and below (`NONE`: unbounded).
    top: u32,
    bottom: u32,
    /// Endpoints through which its left and right walls pass (`None`: unbounded).
    leftp: Option<DVec2>,
    rightp: Option<DVec2>,
    /// Neighbours across the left wall sharing its top (upper) or bottom (lower) segment, and
    /// likewise on the right (`NONE` when there is none).
    upper_left: u32,
    lower_left: u32,
    upper_right: u32,
    lower_right: u32,
    /// Its leaf in the search DAG.
    leaf: u32,
    /// False once the trapezoid has been split by a later segment.
    alive: bool,
}

#[derive(Debug, Clone, Copy)]
enum Node {
    /// Left child: points lexicographically before `point`; right: after it.
    X {
        point: DVec2,
        /// Index of `point` in the builder's vertex list.
        vertex: u32,
        left: u32,
        right: u32,
    },
    /// Children above and below `segment` (within its x-range).
    Y {
        segment: u32,
        above: u32,
        below: u32,
    },
    Leaf {
        trapezoid: u32,
    },
}

/// The map under construction: trapezoids with their links and the search DAG (root: node 0).
#[derive(Debug, Clone)]
pub(super) struct Builder {
    /// Every ring vertex, in ring order (segments and x-nodes refer to them by index).
    vertices: Vec<DVec2>,
    segments: Vec<Segment>,
    trapezoids: Vec<Trapezoid>,
    nodes: Vec<Node>,
    /// The construction's work, counted.
    stats: BuildStats,
    // Scratch buffers of `insert`, reused across segments.
    crossed: Vec<u32>,
    upper_of: Vec<u32>,
    lower_of: Vec<u32>,
}

/// A builder node not yet numbered in the finished DAG (`freeze`).
const UNNUMBERED: u32 = u32::MAX - 2;

impl Builder {
    pub(super) fn build(rings: &[Vec<DVec2>]) -> Result<Self, MapError> {
        // Three trapezoids and about seven nodes per segment, with room for the dead ones; vertex
        // indices below `X_NODE`.
        if rings.iter().map(Vec::len).sum::<usize>() > (u32::MAX as usize) / 16 {
            return Err(MapError::TooLarge);
        }
        let mut segments = Vec::new();
        let mut vertices = Vec::new();
        for ring in rings {
            let n = ring.len();
            let base = vertices.len() as u32;
            vertices.extend_from_slice(ring);
            for i in 0..n {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                if !a.is_finite() || !b.is_finite() {
                    return Err(MapError::NonFinite);
                }
                if a == b {
                    continue;
                }
                let (ia, ib) = (base + i as u32, base + ((i + 1) % n) as u32);
                let interior_above = lex_less(a, b);
                let (left, right, left_vertex, right_vertex) = if interior_above {
                    (a, b, ia, ib)
                } else {
                    (b, a, ib, ia)
                };
                segments.push(Segment {
                    left,
                    right,
                    left_vertex,
                    right_vertex,
                    interior_above,
                });
            }
        }
        crate::shuffle::shuffle(&mut segments, SHUFFLE_SEED);
        let mut map = Builder {
            vertices,
            segments: Vec::with_capacity(segments.len()),
            trapezoids: Vec::with_capacity(4 * segments.len() + 1),
            nodes: Vec::with_capacity(8 * segments.len() + 1),
            stats: BuildStats::default(),
            crossed: Vec::new(),
            upper_of: Vec::new(),
            lower_of: Vec::new(),
        };
        map.new_trapezoid(Trapezoid {
            top: NONE,
            bottom: NONE,
            leftp: None,
            rightp: None,
            upper_left: NONE,
            lower_left: NONE,
            upper_right: NONE,
            lower_right: NONE,
            leaf: NONE,
            alive: true,
        });
        for s in segments {
            map.insert(s)?;
        }
        map.check_status_consistency()?;
        Ok(map)
    }

    /// The finished map: leaves folded into their parents' child slots as inside/outside tags,
    /// internal nodes renumbered in van Emde Boas order (see [`veb_order`]), vertices renumbered
    /// in order of first use.
    pub(super) fn freeze(self) -> TrapezoidalMap {
        // One pass in creation order (leaves and their trapezoids were created together, so this
        // reads the trapezoids nearly sequentially): a leaf's slot is its tag.
        let mut slot: Vec<u32> = self
            .nodes
            .iter()
            .map(|node| match *node {
                Node::Leaf { trapezoid } if self.inside(trapezoid) => LEAF_INSIDE,
                Node::Leaf { .. } => LEAF_OUTSIDE,
                _ => UNNUMBERED,
            })
            .collect();
        let children = |n: u32| match self.nodes[n as usize] {
            Node::X { left, right, .. } => [left, right],
            Node::Y { above, below, .. } => [above, below],
            Node::Leaf { .. } => unreachable!("leaves are tagged"),
        };
        let order = if slot[0] == UNNUMBERED {
            let depth = longest_path(
                self.nodes.len(),
                0,
                |n| slot[n as usize] != UNNUMBERED,
                children,
            );
            veb_order(0, depth, &mut slot, children)
        } else {
            Vec::new()
        };
        let root = if order.is_empty() { slot[0] } else { 0 };
        let mut vertex_id = vec![UNNUMBERED; self.vertices.len()];
        let mut vertices = Vec::new();
        let mut vertex = |v: u32| {
            if vertex_id[v as usize] == UNNUMBERED {
                vertex_id[v as usize] = vertices.len() as u32;
                vertices.push(self.vertices[v as usize]);
            }
            vertex_id[v as usize]
        };
        let nodes: Vec<SearchNode> = order
            .iter()
            .map(|&old| match self.nodes[old as usize] {
                Node::X {
                    vertex: v,
                    left,
                    right,
                    ..
                } => SearchNode {
                    a: X_NODE | vertex(v),
                    b: 0,
                    children: [slot[left as usize], slot[right as usize]],
                },
                Node::Y {
                    segment,
                    above,
                    below,
                } => {
                    let s = &self.segments[segment as usize];
                    SearchNode {
                        a: vertex(s.left_vertex),
                        b: vertex(s.right_vertex),
                        children: [slot[above as usize], slot[below as usize]],
                    }
                }
                Node::Leaf { .. } => unreachable!("leaves are tagged"),
            })
            .collect();
        let depth = longest_path(
            nodes.len(),
            root,
            |n| n >= LEAF_OUTSIDE,
            |n| nodes[n as usize].children,
        );
        TrapezoidalMap {
            nodes,
            vertices,
            root,
            segment_count: self.segments.len(),
            trapezoid_count: self.trapezoids.iter().filter(|t| t.alive).count(),
            depth,
            stats: self.stats,
        }
    }

    /// The face lies in trapezoid `t` (read from its bottom segment).
    fn inside(&self, t: u32) -> bool {
        let b = self.trapezoids[t as usize].bottom;
        b != NONE && self.segments[b as usize].interior_above
    }

    fn new_trapezoid(&mut self, mut t: Trapezoid) -> u32 {
        let id = self.trapezoids.len() as u32;
        self.stats.created_trapezoids += 1;
        t.leaf = self.nodes.len() as u32;
        self.nodes.push(Node::Leaf { trapezoid: id });
        self.trapezoids.push(t);
        id
    }

    fn push_node(&mut self, n: Node) -> u32 {
        self.nodes.push(n);
        (self.nodes.len() - 1) as u32
    }

    /// The trapezoid a new segment `p -> q` starts in: the one just right of `p` on its side of
    /// every segment through `p`.
    fn locate_start(&mut self, p: DVec2, q: DVec2) -> Result<u32, MapError> {
        let mut node = 0u32;
        loop {
            self.stats.located_nodes += 1;
            match self.nodes[node as usize] {
                Node::X {
                    point, left, right, ..
                } => {
                    // A shared endpoint goes right: the new segment extends to the right.
                    node = if lex_less(p, point) { left } else { right };
                }
                Node::Y {
                    segment,
                    above,
                    below,
                } => {
                    let s = &self.segments[segment as usize];
                    let mut o = orient(s.left, s.right, p);
                    if o == 0.0 {
                        if p != s.left {
                            return Err(MapError::Crossing);
                        }
                        // Both start at p: compare directions.
                        o = orient(s.left, s.right, q);
                        if o == 0.0 {
                            return Err(MapError::Overlap);
                        }
                    }
                    node = if o > 0.0 { above } else { below };
                }
                Node::Leaf { trapezoid } => return Ok(trapezoid),
            }
        }
    }

    fn trap(&self, t: u32) -> &Trapezoid {
        &self.trapezoids[t as usize]
    }

    fn trap_mut(&mut self, t: u32) -> &mut Trapezoid {
        &mut self.trapezoids[t as usize]
    }

    /// Points the left-pointing links of `t`'s right neighbour `n` that referred to `old` at `new`.
    fn relink_left(&mut self, n: u32, old: u32, new_upper: u32, new_lower: u32) {
        if n == NONE {
            return;
        }
        let nb = self.trap_mut(n);
        if nb.upper_left == old {
            nb.upper_left = new_upper;
        }
        if nb.lower_left == old {
            nb.lower_left = new_lower;
        }
    }

    /// Points the right-pointing links of `t`'s left neighbour `n` that referred to `old` at `new`.
    fn relink_right(&mut self, n: u32, old: u32, new_upper: u32, new_lower: u32) {
        if n == NONE {
            return;
        }
        let nb = self.trap_mut(n);
        if nb.upper_right == old {
            nb.upper_right = new_upper;
        }
        if nb.lower_right == old {
            nb.lower_right = new_lower;
        }
    }

    fn insert(&mut self, s: Segment) -> Result<(), MapError> {
        let (p, q) = (s.left, s.right);
        debug_assert!(lex_less(p, q), "segment endpoints out of order");
        let seg = self.segments.len() as u32;
        self.segments.push(s);

        // The trapezoids the segment crosses, left to right.
        let start = self.locate_start(p, q)?;
        let mut crossed = std::mem::take(&mut self.crossed);
        let mut upper_of = std::mem::take(&mut self.upper_of);
        let mut lower_of = std::mem::take(&mut self.lower_of);
        crossed.clear();
        upper_of.clear();
        lower_of.clear();
        crossed.push(start);
        loop {
            let t = self.trap(crossed[crossed.len() - 1]);
            // The segment must stay between the trapezoid's top and bottom: a crossing of any
            // existing segment shows up here first (just before it, that segment bounds the
            // trapezoid holding the new one).
            for bound in [t.top, t.bottom] {
                if bound != NONE {
                    let e = &self.segments[bound as usize];
                    segments_conflict(p, q, e.left, e.right)?;
                }
            }
            let Some(r) = t.rightp else { break };
            if !lex_less(r, q) {
                break;
            }
            let o = orient(p, q, r);
            let next = if o > 0.0 {
                t.lower_right
            } else if o < 0.0 {
                t.upper_right
            } else {
                return Err(MapError::Crossing);
            };
            if next == NONE {
                return Err(MapError::Inconsistent);
            }
            debug_assert!(self.trap(next).alive && self.trap(next).leftp == Some(r));
            crossed.push(next);
        }
        self.stats.segments += 1;
        self.stats.destroyed_trapezoids += crossed.len() as u64;

        let first = crossed[0];
        let last = crossed[crossed.len() - 1];
        let d0 = *self.trap(first);
        let blank = Trapezoid {
            top: NONE,
            bottom: NONE,
            leftp: Some(p),
            rightp: None,
            upper_left: NONE,
            lower_left: NONE,
            upper_right: NONE,
            lower_right: NONE,
            leaf: NONE,
            alive: true,
        };

        // The pieces above and below the segment in the first crossed trapezoid.
        let mut upper = self.new_trapezoid(Trapezoid {
            top: d0.top,
            bottom: seg,
            ..blank
        });
        let mut lower = self.new_trapezoid(Trapezoid {
            top: seg,
            bottom: d0.bottom,
            ..blank
        });
        // The piece left of p, unless p is already d0's left wall point.
        let left_piece = if d0.leftp != Some(p) {
            let a = self.new_trapezoid(Trapezoid {
                top: d0.top,
                bottom: d0.bottom,
                leftp: d0.leftp,
                rightp: Some(p),
                upper_left: d0.upper_left,
                lower_left: d0.lower_left,
                upper_right: upper,
                lower_right: lower,
                ..blank
            });
            self.relink_right(d0.upper_left, first, a, a);
            self.relink_right(d0.lower_left, first, a, a);
            self.trap_mut(upper).upper_left = a;
            self.trap_mut(lower).lower_left = a;
            Some(a)
        } else {
            self.trap_mut(upper).upper_left = d0.upper_left;
            self.trap_mut(lower).lower_left = d0.lower_left;
            self.relink_right(d0.upper_left, first, upper, NONE);
            self.relink_right(d0.lower_left, first, NONE, lower);
            None
        };
        upper_of.push(upper);
        lower_of.push(lower);

        // Across each wall the segment passes, the piece on the wall's side is cut; the other
        // side's piece continues (the wall no longer reaches past the segment).
        for j in 1..crossed.len() {
            let (prev_id, cur_id) = (crossed[j - 1], crossed[j]);
            let (prev, cur) = (*self.trap(prev_id), *self.trap(cur_id));
            let Some(r) = cur.leftp else {
                return Err(MapError::Inconsistent);
            };
            if orient(p, q, r) > 0.0 {
                // The wall point is above: the upper piece ends at r, a new one starts.
                let new_upper = self.new_trapezoid(Trapezoid {
                    top: cur.top,
                    bottom: seg,
                    leftp: Some(r),
                    upper_left: cur.upper_left,
                    lower_left: upper,
                    ..blank
                });
                let up = self.trap_mut(upper);
                up.rightp = Some(r);
                up.upper_right = prev.upper_right;
                up.lower_right = new_upper;
                self.relink_left(prev.upper_right, prev_id, upper, NONE);
                self.relink_right(cur.upper_left, cur_id, new_upper, NONE);
                upper = new_upper;
                if prev.bottom != cur.bottom {
                    return Err(MapError::Inconsistent);
                }
            } else {
                let new_lower = self.new_trapezoid(Trapezoid {
                    top: seg,
                    bottom: cur.bottom,
                    leftp: Some(r),
                    upper_left: lower,
                    lower_left: cur.lower_left,
                    ..blank
                });
                let lo = self.trap_mut(lower);
                lo.rightp = Some(r);
                lo.lower_right = prev.lower_right;
                lo.upper_right = new_lower;
                self.relink_left(prev.lower_right, prev_id, NONE, lower);
                self.relink_right(cur.lower_left, cur_id, NONE, new_lower);
                lower = new_lower;
                if prev.top != cur.top {
                    return Err(MapError::Inconsistent);
                }
            }
            upper_of.push(upper);
            lower_of.push(lower);
        }

        // The end: the piece right of q, unless q is already the last trapezoid's right wall point.
        let dk = *self.trap(last);
        self.trap_mut(upper).rightp = Some(q);
        self.trap_mut(lower).rightp = Some(q);
        let right_piece = if dk.rightp != Some(q) {
            let b = self.new_trapezoid(Trapezoid {
                top: dk.top,
                bottom: dk.bottom,
                leftp: Some(q),
                rightp: dk.rightp,
                upper_left: upper,
                lower_left: lower,
                upper_right: dk.upper_right,
                lower_right: dk.lower_right,
                ..blank
            });
            self.relink_left(dk.upper_right, last, b, b);
            self.relink_left(dk.lower_right, last, b, b);
            self.trap_mut(upper).upper_right = b;
            self.trap_mut(lower).lower_right = b;
            Some(b)
        } else {
            self.trap_mut(upper).upper_right = dk.upper_right;
            self.trap_mut(lower).lower_right = dk.lower_right;
            self.relink_left(dk.upper_right, last, upper, NONE);
            self.relink_left(dk.lower_right, last, NONE, lower);
            None
        };

        // Replace the crossed trapezoids' leaves by their sub-DAGs.
        let n = crossed.len();
        for (j, &t) in crossed.iter().enumerate() {
            let above = self.trap(upper_of[j]).leaf;
            let below = self.trap(lower_of[j]).leaf;
            let mut top = Node::Y {
                segment: seg,
                above,
                below,
            };
            if j == n - 1 {
                if let Some(b) = right_piece {
                    let y = self.push_node(top);
                    let right = self.trap(b).leaf;
                    top = Node::X {
                        point: q,
                        vertex: s.right_vertex,
                        left: y,
                        right,
                    };
                }
            }
            if j == 0 {
                if let Some(a) = left_piece {
                    let inner = self.push_node(top);
                    let left = self.trap(a).leaf;
                    top = Node::X {
                        point: p,
                        vertex: s.left_vertex,
                        left,
                        right: inner,
                    };
                }
            }
            let leaf = self.trap(t).leaf;
            self.nodes[leaf as usize] = top;
            let dead = self.trap_mut(t);
            dead.alive = false;
            dead.leaf = NONE;
        }
        self.crossed = crossed;
        self.upper_of = upper_of;
        self.lower_of = lower_of;
        Ok(())
    }

    /// Every live trapezoid's status read from its bottom segment equals that read from its top.
    fn check_status_consistency(&self) -> Result<(), MapError> {
        for (i, t) in self.trapezoids.iter().enumerate() {
            if !t.alive {
                continue;
            }
            let from_top = t.top != NONE && !self.segments[t.top as usize].interior_above;
            if self.inside(i as u32) != from_top {
                return Err(MapError::Inconsistent);
            }
        }
        Ok(())
    }

    /// Checks the map's structure (tests and debugging): neighbour links are mutual and share the
    /// top or bottom segment and the wall point; every live trapezoid has a leaf pointing back at
    /// it; trapezoids have their walls in lexicographic order. Panics with the broken rule.
    pub(super) fn assert_well_formed(&self) {
        for (i, t) in self.trapezoids.iter().enumerate() {
            if !t.alive {
                continue;
            }
            let i = i as u32;
            assert!(
                matches!(self.nodes[t.leaf as usize], Node::Leaf { trapezoid } if trapezoid == i),
                "trapezoid {i}: its leaf does not point back"
            );
            if let (Some(l), Some(r)) = (t.leftp, t.rightp) {
                assert!(lex_less(l, r), "trapezoid {i}: walls out of order");
            }
            // Each neighbour: its link back, whether it shares the boundary segment and wall point.
            type Side<'a> = (
                u32,
                fn(&Trapezoid) -> u32,
                fn(&Trapezoid, &Trapezoid) -> bool,
                &'a str,
            );
            let sides: [Side; 4] = [
                (
                    t.upper_left,
                    |x| x.upper_right,
                    |t, nb| nb.top == t.top && nb.rightp == t.leftp,
                    "upper left",
                ),
                (
                    t.lower_left,
                    |x| x.lower_right,
                    |t, nb| nb.bottom == t.bottom && nb.rightp == t.leftp,
                    "lower left",
                ),
                (
                    t.upper_right,
                    |x| x.upper_left,
                    |t, nb| nb.top == t.top && nb.leftp == t.rightp,
                    "upper right",
                ),
                (
                    t.lower_right,
                    |x| x.lower_left,
                    |t, nb| nb.bottom == t.bottom && nb.leftp == t.rightp,
                    "lower right",
                ),
            ];
            for (n, back, shares, what) in sides {
                if n == NONE {
                    continue;
                }
                let nb = &self.trapezoids[n as usize];
                assert!(nb.alive, "trapezoid {i}: {what} neighbour {n} is dead");
                assert_eq!(
                    back(nb),
                    i,
                    "trapezoid {i}: {what} neighbour {n} does not link back"
                );
                assert!(
                    shares(t, nb),
                    "trapezoid {i}: {what} neighbour {n} shares no boundary segment"
                );
            }
        }
    }
}

fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Whether the segments `p -> q` and `a -> b` (each lexicographically ordered) meet other than at a
/// shared endpoint: a crossing, an endpoint inside the other segment, or a collinear overlap.
fn segments_conflict(p: DVec2, q: DVec2, a: DVec2, b: DVec2) -> Result<(), MapError> {
    let (o1, o2) = (sign(orient(p, q, a)), sign(orient(p, q, b)));
    if o1 == 0 && o2 == 0 {
        // Collinear: their lexicographic ranges may share at most an endpoint.
        return if lex_less(p, b) && lex_less(a, q) {
            Err(MapError::Overlap)
        } else {
            Ok(())
        };
    }
    if p == a || p == b || q == a || q == b {
        return Ok(()); // Not collinear: they meet only there.
    }
    let (o3, o4) = (sign(orient(a, b, p)), sign(orient(a, b, q)));
    if o1 * o2 <= 0 && o3 * o4 <= 0 {
        Err(MapError::Crossing)
    } else {
        Ok(())
    }
}

/// Nodes on the longest path from `root` to a leaf, in a DAG given by `children`, where `is_leaf`
/// tells leaves (not counted) from internal nodes, indexed `0..count` (memoised post-order walk
/// with a stack).
fn longest_path(
    count: usize,
    root: u32,
    is_leaf: impl Fn(u32) -> bool,
    children: impl Fn(u32) -> [u32; 2],
) -> usize {
    if is_leaf(root) {
        return 0;
    }
    let mut depth = vec![0usize; count];
    let mut stack = vec![(root, false)];
    while let Some((n, expanded)) = stack.pop() {
        if depth[n as usize] > 0 {
            continue;
        }
        let kids = children(n);
        if expanded {
            let d = kids
                .iter()
                .map(|&c| if is_leaf(c) { 0 } else { depth[c as usize] })
                .max()
                .unwrap_or(0);
            depth[n as usize] = d + 1;
        } else {
            stack.push((n, true));
            for c in kids {
                if !is_leaf(c) && depth[c as usize] == 0 {
                    stack.push((c, false));
                }
            }
        }
    }
    depth[root as usize]
}

/// Numbers the internal nodes reachable from `root` (those whose `slot` is [`UNNUMBERED`]) in van
/// Emde Boas order, writing each one's new index into `slot` and returning the old indices in the
/// new order. A subtree of height `h` is laid out as its top `h/2` levels, then each subtree
/// hanging below them, recursively: a root-to-leaf path crosses O(log_B n) blocks of B
/// consecutive nodes for every block size B at once (cache lines, pages). In a DAG a node shared
/// by several subtrees goes with the first that reaches it. `height` is the DAG's depth.
fn veb_order(
    root: u32,
    height: usize,
    slot: &mut [u32],
    children: impl Fn(u32) -> [u32; 2],
) -> Vec<u32> {
    fn lay(
        n: u32,
        h: usize,
        slot: &mut [u32],
        order: &mut Vec<u32>,
        children: &impl Fn(u32) -> [u32; 2],
    ) {
        if slot[n as usize] != UNNUMBERED {
            return; // a leaf, or numbered through another parent
        }
        if h <= 1 {
            slot[n as usize] = order.len() as u32;
            order.push(n);
            return;
        }
        let top = h / 2;
        let start = order.len();
        lay(n, top, slot, order, children);
        // Children of the top part still unnumbered hang just below it.
        for k in start..order.len() {
            for c in children(order[k]) {
                lay(c, h - top, slot, order, children);
            }
        }
    }
    let mut order = Vec::new();
    lay(root, height.max(1), slot, &mut order, &children);
    // Nothing is deeper than `height`; this pass only guards that invariant.
    let mut k = 0;
    while k < order.len() {
        for c in children(order[k]) {
            lay(c, height.max(1), slot, &mut order, &children);
        }
        k += 1;
    }
    order
}

//! Trapezoidal map of a polygon with holes: point location in O(log n) expected (paper 3.3,
//! figure 5; de Berg et al., *Computational Geometry*, chapter 6).
//!
//! Built by randomised incremental construction over the rings' segments, shuffled with a
//! fixed-seed generator ([`SHUFFLE_SEED`], so a map is reproducible): expected O(n log n) time and
//! O(n) size. The search structure is a DAG of x-nodes (a segment endpoint), y-nodes (a segment)
//! and leaves (a trapezoid).
//!
//! Degeneracies: "left of" is the lexicographic order `(x, then y)` (a symbolic shear), so vertical
//! segments and shared x-coordinates need no special case; above/below is Shewchuk's exact
//! `orient2d`. Segments may share endpoints (consecutive ring edges, rings touching at a vertex).
//!
//! Boundary convention: the face is **closed**. [`TrapezoidalMap::locate`] reports
//! [`Location::Boundary`] for a point exactly (by the exact predicates) on a ring vertex or edge, and
//! [`TrapezoidalMap::contains`] is true for it. Off the boundary, a point is inside when the
//! trapezoid holding it lies above a segment whose interior side is up.
//!
//! Input contract: rings are closed (last vertex joined to the first), oriented with the interior
//! on their left (outer counter-clockwise, holes clockwise), and no two segments meet except at
//! shared endpoints. Construction checks each new segment exactly against the top and bottom
//! segments of every trapezoid it crosses (a crossing, a vertex inside another segment or a
//! collinear overlap; any two segments that meet wrongly are caught this way, since just before
//! they meet the earlier one bounds the trapezoid holding the later), checks neighbours exist,
//! and at the end that every trapezoid's inside/outside status read from its bottom segment
//! agrees with that read from its top segment (which catches inconsistently oriented rings); it
//! returns a [`MapError`] rather than a wrong map when a check fails.
//!
//! Layout: construction works on a `Builder` (trapezoids with neighbour links, a DAG whose leaves
//! are trapezoids). The finished map keeps only the search DAG: 16-byte nodes (vertex indices and
//! two child slots) in van Emde Boas order, so a search path crosses few cache lines and pages,
//! leaves reduced to an inside/outside tag in their parent's child slot, and the segment endpoints
//! in one array in order of first use by the nodes. A query reads one node per level and its one
//! or two vertices.
//!
//! This module holds the finished map and its queries; `build` holds the construction (the
//! `Builder`, segment insertion, the well-formedness checks) and the freezing into the search DAG.

mod build;

use super::predicates::{lex_less, orient};
use build::Builder;
use glam::DVec2;

/// Seed of the segment shuffle: construction is randomised but reproducible.
pub const SHUFFLE_SEED: u64 = 0x5eed_7a9e_201d_0a11;

/// Where a point lies relative to the face: the face geometry's answer type, shared with the
/// winding-number fallback.
pub use crate::faces::geom::Location;

/// Why a map could not be built: the rings break the input contract.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum MapError {
    #[error("a ring vertex is not finite")]
    NonFinite,
    #[error("two ring segments overlap along a line")]
    Overlap,
    #[error("a ring vertex lies inside another segment, or segments cross")]
    Crossing,
    #[error("rings are inconsistently oriented or cross")]
    Inconsistent,
    #[error("too many segments for 32-bit indices")]
    TooLarge,
}

/// A child slot of a [`SearchNode`] naming a leaf outside the face.
const LEAF_OUTSIDE: u32 = u32::MAX - 1;
/// A child slot naming a leaf inside the face.
const LEAF_INSIDE: u32 = u32::MAX;
/// Marks an x-node in [`SearchNode::a`].
const X_NODE: u32 = 1 << 31;

/// A node of the finished search DAG, 16 bytes (four to a cache line). An x-node has
/// `a = X_NODE | vertex` and children `[left of the vertex, right of it]`; a y-node is the segment
/// from vertex `a` to vertex `b` (lexicographic order) with children `[above, below]`. Children are
/// node indices or a `LEAF_*` tag.
#[derive(Debug, Clone, Copy)]
struct SearchNode {
    a: u32,
    b: u32,
    children: [u32; 2],
}

/// The work of one construction, counted (independent of the memory hierarchy).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BuildStats {
    /// Segments inserted.
    pub segments: u64,
    /// DAG nodes visited locating the segments' left endpoints (leaves included): O(n log n)
    /// expected in all.
    pub located_nodes: u64,
    /// Trapezoids crossed by the inserted segments, each replaced (destroyed): O(n) expected.
    pub destroyed_trapezoids: u64,
    /// Trapezoids created (the initial one included): O(n) expected.
    pub created_trapezoids: u64,
}

impl BuildStats {
    /// DAG nodes visited plus trapezoids crossed.
    pub fn steps(&self) -> u64 {
        self.located_nodes + self.destroyed_trapezoids
    }
}

/// A trapezoidal map's point-location structure.
#[derive(Debug, Clone)]
pub struct TrapezoidalMap {
    /// In van Emde Boas order from the root, `nodes[0]` (empty when the root is a leaf).
    nodes: Vec<SearchNode>,
    /// The segment endpoints the nodes refer to, in order of first use by `nodes`.
    vertices: Vec<DVec2>,
    /// The root's slot: 0, or a `LEAF_*` tag for a map without segments.
    root: u32,
    segment_count: usize,
    trapezoid_count: usize,
    depth: usize,
    stats: BuildStats,
}

impl TrapezoidalMap {
    /// Builds the map of `rings` (see the module's input contract). Repeated consecutive vertices
    /// are skipped; a ring with fewer than two distinct vertices adds nothing.
    pub fn new(rings: &[Vec<DVec2>]) -> Result<Self, MapError> {
        Ok(Builder::build(rings)?.freeze())
    }

    /// Like [`Self::new`], checking the construction's trapezoid links first (tests): panics with
    /// the broken rule.
    pub fn new_checked(rings: &[Vec<DVec2>]) -> Result<Self, MapError> {
        let builder = Builder::build(rings)?;
        builder.assert_well_formed();
        Ok(builder.freeze())
    }

    /// Number of segments in the map.
    pub fn segment_count(&self) -> usize {
        self.segment_count
    }

    /// Number of trapezoids of the map.
    pub fn trapezoid_count(&self) -> usize {
        self.trapezoid_count
    }

    /// Length of the longest search path (nodes; O(log n) expected).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// DAG nodes visited and trapezoids crossed while building: the construction's work
    /// (O(n log n) expected), independent of the memory hierarchy.
    pub fn build_steps(&self) -> u64 {
        self.stats.steps()
    }

    /// The construction's work, itemised.
    pub fn build_stats(&self) -> BuildStats {
        self.stats
    }

    /// Nodes of the search DAG (leaves not counted).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Where `p` lies: inside, outside or exactly on the boundary. Non-finite points are outside.
    pub fn locate(&self, p: DVec2) -> Location {
        self.locate_counting(p).0
    }

    /// The closed face contains `p` (inside or on the boundary).
    pub fn contains(&self, p: DVec2) -> bool {
        self.locate(p) != Location::Outside
    }

    /// Nodes visited locating `p` (for measurements).
    pub fn search_path_length(&self, p: DVec2) -> usize {
        self.locate_counting(p).1
    }

    fn locate_counting(&self, p: DVec2) -> (Location, usize) {
        if !p.is_finite() {
            return (Location::Outside, 0);
        }
        let mut slot = self.root;
        let mut visited = 0;
        loop {
            match slot {
                LEAF_INSIDE => return (Location::Inside, visited),
                LEAF_OUTSIDE => return (Location::Outside, visited),
                _ => {}
            }
            visited += 1;
            let node = self.nodes[slot as usize];
            if node.a & X_NODE != 0 {
                let point = self.vertices[(node.a & !X_NODE) as usize];
                if p == point {
                    return (Location::Boundary, visited);
                }
                slot = node.children[usize::from(!lex_less(p, point))];
            } else {
                let left = self.vertices[node.a as usize];
                let right = self.vertices[node.b as usize];
                let o = orient(left, right, p);
                if o == 0.0 {
                    // The point is within the segment's x-range (the node's region is).
                    return (Location::Boundary, visited);
                }
                slot = node.children[usize::from(o < 0.0)];
            }
        }
    }
}

//! The element hierarchy of one root: a 4-ary tree of sub-elements stored in an arena, with
//! per-node coefficient arrays (per colour channel) for irradiance and unshot radiosity.
//!
//! Also owns the per-node side tables: one `NodeCover` and one `SpreadPoints` (filled when a
//! link first asks, emptied when the solve ends) per node for an extended root, one
//! `NodeReflectance` per node for a root whose reflectance varies, none otherwise. Only
//! [`Hierarchy::of_root`], [`Hierarchy::split_element`] and [`Hierarchy::rebuild_side_tables`]
//! create nodes for the solver, and each keeps the tables in step (`debug_assert_side_tables`).
//!
//! Invariants (checked by [`Hierarchy::assert_well_formed`]):
//! - node 0 is the root, with the identity map; children are created four at a time, contiguous,
//!   and a child's map is its parent's map followed by the shape's child map;
//! - outside a shot (`dh` all zero) every level holds the projection onto its basis of the
//!   function held by the leaves (push-pull consistency): `pull(children) == parent` for `h`, `hd`, `u`.

use super::basis::{child_maps, Basis, ChildMap, MAX_FUNCTIONS};
use super::cover::{self, CoverRules, NodeCover};
use super::near_verdicts::NearVerdicts;
use super::node_reflectance::{self, NodeReflectance};
use crate::domain::{ElementRoot, Shape};
use crate::scene::Rgb;
use glam::DVec2;

/// One element of the hierarchy.
#[derive(Debug, Clone, Copy)]
pub struct Node {
    /// This element's map in the root's reference coordinates.
    pub map: ChildMap,
    pub depth: u8,
    /// Index of the first of four contiguous children, 0 when a leaf.
    pub first_child: u32,
}

impl Node {
    pub fn is_leaf(&self) -> bool {
        self.first_child == 0
    }
}

/// A node's spread points on the face, in root coordinates, once asked for.
pub(super) type SpreadPoints = std::sync::OnceLock<Box<[DVec2]>>;

/// The hierarchy of one element root. Coefficient arrays hold `len` entries per node.
#[derive(Debug, Clone, Default)]
pub struct Hierarchy {
    pub nodes: Vec<Node>,
    /// Irradiance H received, all orders of light.
    pub h: Vec<Rgb>,
    /// Irradiance received straight from emitters (and, later, punctual lights).
    pub hd: Vec<Rgb>,
    /// Unshot radiosity.
    pub u: Vec<Rgb>,
    /// Irradiance gathered at this node during the current shot, not yet pushed and pulled.
    pub dh: Vec<Rgb>,
    /// Basis functions per node.
    pub len: usize,
    /// Whether `dh` holds anything.
    pub touched: bool,
    /// Extended roots only: per node, how it covers the face ([`super::cover`]); empty otherwise.
    pub covers: Vec<NodeCover>,
    /// Roots whose reflectance varies only: per node, its reflectance
    /// ([`super::node_reflectance`]); empty otherwise (the root's `rho` holds everywhere).
    pub reflectance: Vec<NodeReflectance>,
    /// Extended roots only: per node, where its spread points cast their rays
    /// ([`ReceiverNode::spread_point`](super::source::ReceiverNode::spread_point)), computed when
    /// a link to the node first asks for them and emptied when the solve ends; empty for a
    /// native root.
    pub(super) spread_points: Vec<SpreadPoints>,
    /// The shadow-ray verdicts of the near links this root received in indirect shots, kept for
    /// its shooters' next shots ([`super::near_verdicts`]); emptied when the solve ends.
    pub(super) near_verdicts: NearVerdicts,
}

impl Hierarchy {
    pub fn new(len: usize) -> Self {
        Hierarchy {
            nodes: vec![Node {
                map: ChildMap::IDENTITY,
                depth: 0,
                first_child: 0,
            }],
            h: vec![[0.0; 3]; len],
            hd: vec![[0.0; 3]; len],
            u: vec![[0.0; 3]; len],
            dh: vec![[0.0; 3]; len],
            len,
            touched: false,
            covers: Vec::new(),
            reflectance: Vec::new(),
            spread_points: Vec::new(),
            near_verdicts: NearVerdicts::default(),
        }
    }

    /// The hierarchy of `root` before the solve: its root node, with its side tables.
    pub(crate) fn of_root(root: &ElementRoot, basis: &Basis, cover_rules: &CoverRules) -> Self {
        let mut h = Hierarchy::new(basis.len());
        h.extend_side_tables(root, basis, cover_rules);
        h
    }

    /// Splits leaf `node` of `root`'s hierarchy (as [`Hierarchy::split`]) and gives the children
    /// their side tables; returns the first child.
    pub(crate) fn split_element(
        &mut self,
        node: usize,
        root: &ElementRoot,
        basis: &Basis,
        cover_rules: &CoverRules,
    ) -> usize {
        let first = self.split(node, basis, root.shape);
        self.extend_side_tables(root, basis, cover_rules);
        first
    }

    /// Recomputes every node's side tables (a hierarchy read back from a saved solution).
    pub(crate) fn rebuild_side_tables(
        &mut self,
        root: &ElementRoot,
        basis: &Basis,
        cover_rules: &CoverRules,
    ) {
        self.covers.clear();
        self.reflectance.clear();
        self.spread_points.clear();
        self.extend_side_tables(root, basis, cover_rules);
    }

    /// Gives the nodes that have none their cover, spread points' cell and reflectance.
    fn extend_side_tables(&mut self, root: &ElementRoot, basis: &Basis, cover_rules: &CoverRules) {
        cover::extend(self, root, cover_rules, basis);
        let covers = self.covers.len();
        self.spread_points
            .resize_with(covers, SpreadPoints::default);
        node_reflectance::extend(self, root);
        self.debug_assert_side_tables(root);
    }

    /// The side tables' invariant: one entry per node where the root needs them, none elsewhere.
    pub(crate) fn debug_assert_side_tables(&self, root: &ElementRoot) {
        let per_node = |needed: bool| if needed { self.nodes.len() } else { 0 };
        debug_assert_eq!(
            self.covers.len(),
            per_node(root.mask.is_some()),
            "one cover per node of an extended root, none for a native one"
        );
        debug_assert_eq!(
            self.spread_points.len(),
            self.covers.len(),
            "spread points kept beside each cover"
        );
        debug_assert_eq!(
            self.reflectance.len(),
            per_node(root.reflectance.is_some()),
            "one reflectance per node of a root whose reflectance varies"
        );
    }

    pub fn coeffs<'a>(&self, array: &'a [Rgb], node: usize) -> &'a [Rgb] {
        &array[node * self.len..(node + 1) * self.len]
    }

    /// The bytes this hierarchy holds, as allocated: the struct, its node entries, the four
    /// coefficient arrays and the side tables (`SolveStats::bytes_per_element`, taken after
    /// [`Hierarchy::forget_solve_caches`]). Grows with the nodes alone there
    /// (`bytes_grow_with_the_nodes`); during a solve, also with the spread points asked.
    pub fn bytes(&self) -> u64 {
        use std::mem::size_of;
        let coefficients = [&self.h, &self.hd, &self.u, &self.dh]
            .iter()
            .map(|a| a.capacity())
            .sum::<usize>();
        (size_of::<Self>()
            + self.nodes.capacity() * size_of::<Node>()
            + coefficients * size_of::<Rgb>()
            + self.covers.capacity() * size_of::<NodeCover>()
            + self.reflectance.capacity() * size_of::<NodeReflectance>()
            + self.spread_points.capacity() * size_of::<SpreadPoints>()
            + self
                .spread_points
                .iter()
                .filter_map(|p| p.get())
                .map(|p| p.len() * size_of::<DVec2>())
                .sum::<usize>()) as u64
    }

    /// Empties what the solve kept only to save work (the near links' verdicts, the spread
    /// points): called when the solve ends.
    pub(super) fn forget_solve_caches(&mut self) {
        self.near_verdicts.clear();
        for points in &mut self.spread_points {
            points.take();
        }
    }

    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.is_leaf()).count()
    }

    /// Splits leaf `node` into four children holding the pushed coefficients; returns the first child.
    pub fn split(&mut self, node: usize, basis: &Basis, shape: Shape) -> usize {
        debug_assert!(self.nodes[node].is_leaf());
        let first = self.nodes.len();
        let parent = self.nodes[node];
        let maps = child_maps(shape);
        for (c, m) in maps.iter().enumerate() {
            self.nodes.push(Node {
                map: parent.map.then(m),
                depth: parent.depth + 1,
                first_child: 0,
            });
            for array in [0, 1, 2] {
                let arr = match array {
                    0 => &mut self.h,
                    1 => &mut self.hd,
                    _ => &mut self.u,
                };
                let mut child = [[0.0; 3]; MAX_FUNCTIONS];
                basis.push(
                    c,
                    &arr[node * self.len..(node + 1) * self.len],
                    &mut child[..self.len],
                );
                arr.extend_from_slice(&child[..self.len]);
            }
            self.dh.extend(std::iter::repeat_n([0.0; 3], self.len));
        }
        self.nodes[node].first_child = first as u32;
        first
    }

    /// Pushes `dh` down to the leaves and pulls it back up, adding the result to `h` (and `hd` when
    /// `direct`) and the reflected radiosity to `u`: `rho * result` with the root's constant
    /// `rho`, or, where the reflectance varies (`reflectance` not empty), each leaf's own
    /// reflectance times its result, pulled up the tree. Clears `dh`.
    pub fn push_pull(&mut self, basis: &Basis, rho: Rgb, direct: bool) {
        let zero = [[0.0; 3]; MAX_FUNCTIONS];
        self.push_pull_node(0, &zero, basis, rho, direct);
        self.touched = false;
    }

    /// Adds the irradiance `e`, constant over the root, as [`Hierarchy::push_pull`] of `e`
    /// gathered at the root would (basis function 0 is 1 on every element, so a constant's
    /// coefficients are `(e, 0, ..)` on each): `h` (and `hd` when `direct`) gain `e` and `u`
    /// gains `rho e` at every node. For a root whose reflectance is the constant `rho`
    /// (`reflectance` empty); `dh` is left alone (`add_constant_is_push_pull_of_a_constant`).
    pub fn add_constant(&mut self, e: Rgb, rho: Rgb, direct: bool) {
        debug_assert!(self.reflectance.is_empty());
        let n = self.len;
        for i in (0..self.nodes.len()).map(|node| node * n) {
            for k in 0..3 {
                self.h[i][k] += e[k];
                self.u[i][k] += rho[k] * e[k];
                if direct {
                    self.hd[i][k] += e[k];
                }
            }
        }
    }

    /// Returns the node's increments of `h` and of `u`.
    fn push_pull_node(
        &mut self,
        node: usize,
        inherited: &[Rgb; MAX_FUNCTIONS],
        basis: &Basis,
        rho: Rgb,
        direct: bool,
    ) -> ([Rgb; MAX_FUNCTIONS], [Rgb; MAX_FUNCTIONS]) {
        let varying = !self.reflectance.is_empty();
        let n = self.len;
        let mut total = *inherited;
        for i in 0..n {
            for k in 0..3 {
                total[i][k] += self.dh[node * n + i][k];
            }
            self.dh[node * n + i] = [0.0; 3];
        }
        let first = self.nodes[node].first_child as usize;
        let mut reflected = [[0.0; 3]; MAX_FUNCTIONS];
        let result = if first == 0 {
            let leaf_rho = self.reflectance.get(node).map_or(rho, |r| r.mean);
            for i in 0..n {
                for k in 0..3 {
                    reflected[i][k] = leaf_rho[k] * total[i][k];
                }
            }
            total
        } else {
            let mut result = [[0.0; 3]; MAX_FUNCTIONS];
            for c in 0..4 {
                let mut child_inh = [[0.0; 3]; MAX_FUNCTIONS];
                basis.push(c, &total[..n], &mut child_inh[..n]);
                let (r, du) = self.push_pull_node(first + c, &child_inh, basis, rho, direct);
                basis.pull_add(c, &r[..n], &mut result[..n]);
                basis.pull_add(c, &du[..n], &mut reflected[..n]);
            }
            result
        };
        if !varying {
            // A constant reflectance commutes with the pull: the historical (bit-identical) form.
            for i in 0..n {
                for k in 0..3 {
                    reflected[i][k] = rho[k] * result[i][k];
                }
            }
        }
        for i in 0..n {
            for k in 0..3 {
                self.h[node * n + i][k] += result[i][k];
                self.u[node * n + i][k] += reflected[i][k];
                if direct {
                    self.hd[node * n + i][k] += result[i][k];
                }
            }
        }
        (result, reflected)
    }

    /// The leaf containing root point `st`, and `st` in that leaf's local coordinates.
    pub fn locate(&self, st: DVec2, shape: Shape) -> (usize, DVec2) {
        let mut node = 0;
        loop {
            let first = self.nodes[node].first_child as usize;
            let local = self.nodes[node].map.local(st);
            if first == 0 {
                return (node, local);
            }
            node = first + child_index(shape, local);
        }
    }

    /// Checks the structural and push-pull invariants (tests call it after every change).
    pub fn assert_well_formed(&self, basis: &Basis, shape: Shape) {
        let n = self.len;
        assert_eq!(self.h.len(), self.nodes.len() * n);
        assert_eq!(self.u.len(), self.nodes.len() * n);
        let maps = child_maps(shape);
        for (i, node) in self.nodes.iter().enumerate() {
            let first = node.first_child as usize;
            if first == 0 {
                continue;
            }
            assert!(
                first > i && first + 4 <= self.nodes.len(),
                "children of {i} out of order"
            );
            for (c, m) in maps.iter().enumerate() {
                let child = &self.nodes[first + c];
                assert_eq!(child.depth, node.depth + 1);
                let expected = node.map.then(m);
                assert!((child.map.o - expected.o).length() < 1e-12);
            }
            for array in [&self.h, &self.u, &self.hd] {
                let mut pulled = [[0.0; 3]; MAX_FUNCTIONS];
                for c in 0..4 {
                    basis.pull_add(
                        c,
                        &array[(first + c) * n..(first + c + 1) * n],
                        &mut pulled[..n],
                    );
                }
                for a in 0..n {
                    for k in 0..3 {
                        let p = array[i * n + a][k];
                        assert!(
                            (pulled[a][k] - p).abs() <= 1e-9 * (1.0 + p.abs()),
                            "node {i} coefficient {a}: pulled {} vs stored {p}",
                            pulled[a][k]
                        );
                    }
                }
            }
        }
    }
}

/// Checks that `nodes` form a tree as [`Hierarchy`] builds them (node 0 the root at depth 0; a
/// parent's four children contiguous, after it, one level deeper, each node the child of exactly
/// one parent) with finite, non-degenerate maps, so that [`Hierarchy::locate`] terminates and
/// never indexes out of bounds. For nodes read from outside (a saved solution).
pub fn check_tree(nodes: &[Node]) -> Result<(), String> {
    if nodes.first().is_none_or(|n| n.depth != 0) {
        return Err("no root node at depth 0".into());
    }
    let mut claimed = vec![false; nodes.len()];
    for (i, node) in nodes.iter().enumerate() {
        let m = &node.map;
        let det = m.e1.perp_dot(m.e2);
        if ![m.o, m.e1, m.e2].iter().all(|v| v.is_finite()) || !det.is_finite() || det == 0.0 {
            return Err(format!("node {i} has a degenerate or non-finite map"));
        }
        if node.is_leaf() {
            continue;
        }
        let first = node.first_child as usize;
        if first <= i || first.checked_add(4).is_none_or(|end| end > nodes.len()) {
            return Err(format!("node {i}'s children are out of order or bounds"));
        }
        for c in first..first + 4 {
            if claimed[c] || Some(nodes[c].depth) != node.depth.checked_add(1) {
                return Err(format!("node {c} is not a proper child of node {i}"));
            }
            claimed[c] = true;
        }
    }
    if let Some(orphan) = (1..nodes.len()).find(|&i| !claimed[i]) {
        return Err(format!("node {orphan} has no parent"));
    }
    Ok(())
}

/// Which child of a reference shape contains local point `st` (ties go to the lower index).
pub fn child_index(shape: Shape, st: DVec2) -> usize {
    match shape {
        Shape::Parallelogram => (st.x >= 0.5) as usize + 2 * (st.y >= 0.5) as usize,
        Shape::Triangle => {
            if st.x + st.y <= 0.5 {
                0
            } else if st.x >= 0.5 {
                1
            } else if st.y >= 0.5 {
                2
            } else {
                3
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `add_constant` against `push_pull` of the same constant gathered at the root, on a tree
    /// split unevenly, every order and shape, direct or not.
    #[test]
    fn add_constant_is_push_pull_of_a_constant() {
        let (e, rho) = ([0.7, -0.2, 3.0], [0.5, 0.25, 0.9]);
        for shape in [Shape::Triangle, Shape::Parallelogram] {
            for order in 1..=3 {
                let basis = Basis::new(shape, order);
                let mut tree = Hierarchy::new(basis.len());
                for node in [0, 2, 3, 5, 9, 10] {
                    tree.split(node, &basis, shape);
                }
                // Something already stored, not constant.
                for (i, c) in tree.h.iter_mut().enumerate() {
                    *c = [i as f64 * 0.1, 1.0, -0.5];
                }
                tree.u = tree.h.iter().map(|c| c.map(|x| x * 0.3)).collect();
                tree.hd = tree.u.clone();
                for direct in [false, true] {
                    let mut pushed = tree.clone();
                    pushed.dh[0] = e;
                    pushed.push_pull(&basis, rho, direct);
                    let mut added = tree.clone();
                    added.add_constant(e, rho, direct);
                    for (a, b) in [
                        (&added.h, &pushed.h),
                        (&added.u, &pushed.u),
                        (&added.hd, &pushed.hd),
                    ] {
                        for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
                            assert!((x - y).abs() < 1e-12, "{shape:?} M{order}: {x} vs {y}");
                        }
                    }
                    assert!(added.dh.iter().flatten().all(|&x| x == 0.0));
                }
            }
        }
    }

    #[test]
    fn bytes_grow_with_the_nodes() {
        // Per node: its entry and `len` coefficients in each of the four arrays (twice that at
        // most, for the vectors' spare capacity); nothing else grows.
        let basis = Basis::new(Shape::Parallelogram, 2);
        let mut h = Hierarchy::new(basis.len());
        let per_node = std::mem::size_of::<Node>() + 4 * basis.len() * std::mem::size_of::<Rgb>();
        // Nodes split in index order: breadth first, every node a leaf when its turn comes.
        for node in 0..300 {
            h.split(node, &basis, Shape::Parallelogram);
            let nodes = h.nodes.len();
            let bytes = h.bytes() as usize - std::mem::size_of::<Hierarchy>();
            assert!(
                bytes >= per_node * nodes && bytes <= 2 * per_node * nodes,
                "{bytes} bytes for {nodes} nodes"
            );
        }
    }
}

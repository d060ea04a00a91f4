//! The node-sum check after a shot: each receiver node is judged on the sum of the links it
//! gathered, and gives back to its children the links that carry the error: each to the
//! children where its points err, the others taking its coefficients pushed down.
//!
//! Invariants: links only ever go to a node's descendants (larger indices), so nodes taken in index
//! order see complete records, and the result is deterministic; a link given back is sent again
//! as the very part that sent it (rebuilt from its path) and taken back by exactly what it added;
//! a child it is not sent to gathers the link's exact restriction (`Basis::push`), so what the
//! node held there is unchanged.

use super::basis::MAX_FUNCTIONS;
use super::element::Patch;
use super::hierarchy::Hierarchy;
use super::oracle::{max_deviation, oracle_weight};
use super::refine::{gather, take_back, Shot, ShotContext};
use super::shot_record::{NodeSum, Parts, ShotRecord};
use super::{DETAIL_REL, MAX_DEPTH};
use crate::domain::ElementRoot;
use crate::scene::Rgb;
use std::sync::atomic::Ordering;

impl ShotContext<'_> {
    /// The deviation a node of `rroot` is judged by, of a link's or a sum's point values from its
    /// coefficients: the oracle's at the control and check points, weighted by the root's rho.
    /// One function for the links (when recorded) and the sums (when judged).
    pub(super) fn node_sum_deviation<'s>(
        &'s self,
        rroot: &ElementRoot,
    ) -> impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> f64 + 's {
        let nr = self.bases.of(rroot.shape).len();
        let weight = oracle_weight(self.quantity, rroot.rho);
        let psi = self.psi.of(rroot.shape);
        move |e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS]| max_deviation(psi, e, dh, nr, weight)
    }

    /// [`Self::node_sum_deviation`] per child of the node: the largest over the points inside
    /// each child (a point on a boundary counts for every child it touches).
    pub(super) fn node_sum_child_deviation<'s>(
        &'s self,
        rroot: &ElementRoot,
    ) -> impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> [f64; 4] + 's {
        let nr = self.bases.of(rroot.shape).len();
        let weight = oracle_weight(self.quantity, rroot.rho);
        let psi = self.psi.of(rroot.shape);
        let kids = self.psi.children_of(rroot.shape);
        move |e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS]| {
            super::oracle::child_deviation(psi, kids, e, dh, nr, weight)
        }
    }

    /// After a shot's links to one receiver are gathered, judges each node on the sum of the
    /// links it gathered. A large source split for its visibility sends many links, each of
    /// which passes the oracle while their sum, a shadow's edge across the node, is not
    /// represented within the budget (an eave's shadow on the top of a wall). Such a node gives
    /// back the links that carry the error and they go to its children; down the hierarchy until
    /// every node that received light passes or cannot be split. Nodes are taken in index order:
    /// links only ever go to a node's descendants, whose indices are larger, so a node's record
    /// is complete when it is judged, and the order (so the result) is deterministic.
    ///
    /// A link given back is sent again as the part its path leads to from the record's start
    /// (`Parts`, by the shot's own `children`: the part the recursion had), and taken back by the
    /// coefficients it was gathered with. A link goes as seen whole to each child
    /// where all its traced rays passed (from the node's rule and check points inside that child
    /// to the part's), if the child is fully covered or native
    /// ([`Rays::AllPass`](super::source::Rays)): the node's rays there sampled the space between
    /// the child and the part; the child's own children, and its links when re-sent further,
    /// trace again.
    /// The record's largest size goes to `link_records`.
    pub(super) fn refine_by_node_sums<S: Shot>(
        &self,
        shot: &S,
        mut record: ShotRecord<S::Part>,
        rcv_index: usize,
        rcv: &mut Hierarchy,
    ) {
        if let Some(root) = record.take_root() {
            self.judge_nodes(shot, &root, &mut record, rcv_index, rcv);
        }
        let peak = record.peak();
        let mut largest = self.link_records.lock().unwrap_or_else(|e| e.into_inner());
        *largest = largest.max(peak);
    }

    /// The deviation a node of area `area` may show: the threshold's share, lowered in a direct
    /// shot to [`DETAIL_REL`] of the node's brightest point, but not below the detail
    /// threshold's share. A sharp shadow limit within the threshold still misplaces a few
    /// percent of the light next to it; the cost stays where the detail is (tests/stability.rs,
    /// `a_floor_point_at_the_limit_of_a_box_shadow_under_a_large_emitting_wall`).
    fn node_budget(
        &self,
        sum: &NodeSum,
        area: f64,
        deviation: impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> f64,
    ) -> f64 {
        let budget = self.threshold / area;
        if self.detail_threshold >= self.threshold {
            return budget;
        }
        let relative = DETAIL_REL * sum.peak_value(deviation);
        budget.min(relative.max(self.detail_threshold / area))
    }

    fn judge_nodes<S: Shot>(
        &self,
        shot: &S,
        root: &S::Part,
        record: &mut ShotRecord<S::Part>,
        rcv_index: usize,
        rcv: &mut Hierarchy,
    ) {
        let rroot = &self.roots[rcv_index];
        let nr = self.bases.of(rroot.shape).len();
        let deviation = self.node_sum_deviation(rroot);
        let mut parts = Parts::new(shot, root);
        while let Some((b, sum)) = record.pop_first() {
            if self.cancel.load(Ordering::Relaxed) {
                return;
            }
            // One link: its own oracle judged it.
            if sum.link_count() < 2 {
                continue;
            }
            let rnode = rcv.nodes[b];
            let rp = Patch::new(rroot, &rnode.map);
            if rnode.depth >= MAX_DEPTH || rp.min_edge() * 0.5 < self.min_edge {
                continue;
            }
            let allowed = self.node_budget(&sum, rp.area, &deviation);
            let Some(resend) = sum.links_to_resend(allowed, &deviation) else {
                continue;
            };
            self.node_sum_splits.fetch_add(1, Ordering::Relaxed);
            // Taken back: no longer links of this node (each is counted again where it lands).
            self.links.sub(resend.len() as u64);
            for dh in resend.coefficients() {
                debug_assert_eq!(dh.len(), nr);
                take_back(rcv, b, dh);
            }
            let first = self.first_child(rcv, b, rroot);
            debug_assert!(first > b, "children come after their parent");
            let sources: Vec<S::Part> = resend
                .sources
                .iter()
                .map(|&path| parts.get(path).clone())
                .collect();
            // A child where the link's points err within its share takes the link's
            // coefficients pushed down (their exact restriction), as if the node had kept it.
            let basis = self.bases.of(rroot.shape);
            let mut child_dh = [[0.0; 3]; MAX_FUNCTIONS];
            let mut pushed = 0;
            for (dh, &children) in resend.coefficients().zip(&resend.children) {
                // Counted once however many children take it, as a kept link was.
                pushed += u64::from(children != 0b1111);
                for c in (0..4).filter(|c| children & (1 << c) == 0) {
                    basis.push(c, dh, &mut child_dh[..nr]);
                    gather(rcv, first + c, &child_dh[..nr]);
                }
            }
            self.links.add(pushed);
            let links: Vec<_> = (0..4)
                .flat_map(|c| {
                    let sources = &sources;
                    resend
                        .links_to(c)
                        .map(move |(i, link)| (&sources[i], link, first + c))
                })
                .collect();
            self.transfer_all(shot, &links, rcv_index, rcv, record);
        }
    }
}

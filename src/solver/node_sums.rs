//! The node-sum check after a shot: each receiver node is judged on the sum of the links it
//! gathered, and gives back to its children the links that carry the error.
//!
//! Invariant: links only ever go to a node's descendants (larger indices), so nodes taken in index
//! order see complete records, and the result is deterministic.

use super::basis::MAX_FUNCTIONS;
use super::element::Patch;
use super::hierarchy::Hierarchy;
use super::oracle::{max_deviation, oracle_weight};
use super::refine::{take_back, Shot, ShotContext};
use super::shot_record::ShotRecord;
use super::MAX_DEPTH;
use crate::scene::Rgb;
use std::sync::atomic::Ordering;

impl ShotContext<'_> {
    /// After a shot's links to one receiver are gathered, judges each node on the sum of the
    /// links it gathered. A large source split for its visibility sends many links, each of
    /// which passes the oracle while their sum, a shadow's edge across the node, is not
    /// represented within the budget (an eave's shadow on the top of a wall). Such a node gives
    /// back the links that carry the error and they go to its children; down the hierarchy until
    /// every node that received light passes or cannot be split. Nodes are taken in index order:
    /// links only ever go to a node's descendants, whose indices are larger, so a node's record
    /// is complete when it is judged, and the order (so the result) is deterministic.
    pub(super) fn refine_by_node_sums<S: Shot>(
        &self,
        shot: &S,
        mut record: ShotRecord<S::Part>,
        rcv_index: usize,
        rcv: &mut Hierarchy,
    ) {
        let rroot = &self.roots[rcv_index];
        let rbasis = self.bases.of(rroot.shape);
        let nr = rbasis.len();
        let weight = oracle_weight(self.quantity, rroot.rho);
        let psi = self.psi.of(rroot.shape);
        let deviation =
            |e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS]| max_deviation(psi, e, dh, nr, weight);
        while let Some((b, sum)) = record.nodes.pop_first() {
            if self.cancel.load(Ordering::Relaxed) {
                return;
            }
            // One link: its own oracle judged it.
            if sum.links.len() < 2 {
                continue;
            }
            let rnode = rcv.nodes[b];
            let rp = Patch::new(rroot, &rnode.map);
            if rnode.depth >= MAX_DEPTH || rp.min_edge() * 0.5 < self.min_edge {
                continue;
            }
            let Some(resend) = sum.links_to_resend(self.threshold / rp.area, deviation) else {
                continue;
            };
            self.node_sum_splits.fetch_add(1, Ordering::Relaxed);
            // Taken back: no longer links of this node (each is counted again where it lands).
            self.links.fetch_sub(resend.len() as u64, Ordering::Relaxed);
            for l in &resend {
                take_back(rcv, b, &l.dh[..nr]);
            }
            let first = self.first_child(rcv, b, rroot);
            debug_assert!(first > b, "children come after their parent");
            for c in 0..4 {
                for l in &resend {
                    self.transfer(shot, &l.source, rcv_index, rcv, first + c, &mut record);
                }
            }
        }
    }
}

//! What one shot's links delivered to each node of one receiver, kept until the shot is over so
//! that each node can be judged on the sum of its links (see `ShotContext::refine_by_node_sums`).
//!
//! Owns [`ShotRecord`]: per node, the sum of its links' irradiance at the node's rule points then
//! check points and the sum of their coefficients; per link only what judging and re-sending it
//! needs: its source as a [`SourcePath`] (the children taken from the part the shot started
//! from, rebuilt by [`Parts`]), its own deviation over the points inside each of the node's four
//! children, the children where all its traced rays passed, and its coefficients (to take it
//! back exactly).
//! A link that fails its share goes again only to the children where it fails
//! ([`NodeSum::links_to_resend`]; `a_link_goes_again_only_to_the_children_where_it_errs`).
//! A link's record costs `LINK_ENTRY_BYTES + nr * size_of::<Rgb>()` bytes whatever its source
//! (`a_recorded_link_costs_its_path_deviation_and_coefficients_whatever_the_part`); point values
//! are kept per node, so they grow with elements, not with links.
//!
//! Invariants: a node's sums are the sums of its recorded links, point by point and coefficient by
//! coefficient, added in the order the links came; each link's deviations are the ones its values
//! had against its coefficients, per child; `link_bytes` is the allocated size of the per-link
//! entries held.

use super::basis::MAX_FUNCTIONS;
use super::refine::{Link, Shot};
use super::source::Rays;
use crate::scene::Rgb;
use std::collections::BTreeMap;
use std::mem::size_of;

/// Where a part of a shot lies under the part the shot's recursion started from: the child taken
/// at each split (two bits a level, the first split lowest) and the number of splits (the top
/// byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct SourcePath(u32);

impl SourcePath {
    /// The part the recursion started from.
    pub const ROOT: SourcePath = SourcePath(0);
    /// Splits a path can hold (two bits each below the depth byte).
    pub const MAX_SPLITS: u32 = 12;
    const DEPTH_SHIFT: u32 = 24;

    pub fn depth(self) -> u32 {
        self.0 >> Self::DEPTH_SHIFT
    }

    /// The path of child `c` of the part at `self`.
    pub fn child(self, c: usize) -> SourcePath {
        let d = self.depth();
        assert!(
            d < Self::MAX_SPLITS && c < 4,
            "a source path holds 12 splits"
        );
        let steps = self.0 & ((1 << Self::DEPTH_SHIFT) - 1);
        SourcePath(((d + 1) << Self::DEPTH_SHIFT) | steps | ((c as u32) << (2 * d)))
    }

    /// The child taken at split `level` (0: the first).
    fn step(self, level: u32) -> usize {
        ((self.0 >> (2 * level)) & 3) as usize
    }

    /// The path of the ancestor after the first `level` splits.
    fn prefix(self, level: u32) -> SourcePath {
        SourcePath((level << Self::DEPTH_SHIFT) | (self.0 & ((1 << (2 * level)) - 1)))
    }
}

// Sources are split at most `MAX_DEPTH` times below the shooter's root (`SourceSplit::can_split`).
const _: () = assert!(super::MAX_DEPTH as u32 <= SourcePath::MAX_SPLITS);

/// One link's entry (its coefficients are kept beside it, `nr` per link).
#[derive(Debug, Clone, Copy)]
struct LinkEntry {
    source: SourcePath,
    /// The node's children all of whose points' rays passed ([`Received::seen_whole`](
    /// super::transfer::Received)): where the link, re-sent, is taken as seen whole.
    seen_whole: u8,
    /// The oracle's deviation of the link's point values from its coefficients, over the points
    /// inside each of the node's four children.
    deviation: [f32; 4],
}

/// Bytes of one link's entry beside its `nr` coefficients.
pub(super) const LINK_ENTRY_BYTES: usize = size_of::<LinkEntry>();

// A link's entry is a path, a child mask and a deviation: never its source part or its point
// values.
const _: () = assert!(LINK_ENTRY_BYTES <= 24);

/// The per-link entries of a record at their largest: their bytes (as allocated) and the links
/// held then.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct LinkBytes {
    pub bytes: u64,
    pub links: u64,
}

impl LinkBytes {
    /// The larger of two peaks: by bytes, then by links (whatever order receivers finish in).
    pub fn max(self, other: LinkBytes) -> LinkBytes {
        if (other.bytes, other.links) > (self.bytes, self.links) {
            other
        } else {
            self
        }
    }
}

/// The links one receiver gathered during a shot, per node.
pub(super) struct ShotRecord<P> {
    /// The part the shot's recursion started from: every recorded path leads from it.
    root: Option<P>,
    /// In node order: the check takes nodes parents first (see `refine_by_node_sums`).
    nodes: BTreeMap<usize, NodeSum>,
    /// The links held now and their entries' bytes.
    held: LinkBytes,
    /// `held` at its largest.
    peak: LinkBytes,
}

impl<P> Default for ShotRecord<P> {
    fn default() -> Self {
        ShotRecord {
            root: None,
            nodes: BTreeMap::new(),
            held: LinkBytes::default(),
            peak: LinkBytes::default(),
        }
    }
}

/// One node's links from one shot and their sums.
pub(super) struct NodeSum {
    /// Irradiance at the node's rule points, then at its check points.
    pub e: Vec<Rgb>,
    /// The node's coefficients from these links.
    pub dh: [Rgb; MAX_FUNCTIONS],
    links: Vec<LinkEntry>,
    /// `nr` coefficients per link, in the order of `links`.
    link_dh: Vec<Rgb>,
}

impl NodeSum {
    /// The largest value `deviation` gives the sum's point values against no light at all: the
    /// node's brightest point, in the deviation's own weighting.
    pub fn peak_value(&self, deviation: impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> f64) -> f64 {
        deviation(&self.e, &[[0.0; 3]; MAX_FUNCTIONS])
    }

    pub fn link_count(&self) -> usize {
        self.links.len()
    }

    fn link_bytes(&self) -> u64 {
        (self.links.capacity() * LINK_ENTRY_BYTES + self.link_dh.capacity() * size_of::<Rgb>())
            as u64
    }
}

fn add_rgb(acc: &mut [Rgb], x: &[Rgb]) {
    for (a, x) in acc.iter_mut().zip(x) {
        for ch in 0..3 {
            a[ch] += x[ch];
        }
    }
}

impl<P> ShotRecord<P> {
    /// Sets the part the shot's recursion starts from (once per record).
    pub fn start_from(&mut self, root: &P)
    where
        P: Clone,
    {
        debug_assert!(self.root.is_none(), "one recursion per record");
        self.root = Some(root.clone());
    }

    /// Takes the part the recursion started from (the paths' origin).
    pub fn take_root(&mut self) -> Option<P> {
        self.root.take()
    }

    /// Records a link gathered at node `b`: its values `e` at the node's points, its coefficients
    /// `dh` (the first `nr` kept with the link), `deviation` of `e` from `dh` over the points
    /// inside each of the node's children, its source, and the children where all its rays
    /// passed.
    #[allow(clippy::too_many_arguments)]
    pub fn add(
        &mut self,
        b: usize,
        e: &[Rgb],
        dh: &[Rgb; MAX_FUNCTIONS],
        nr: usize,
        deviation: [f64; 4],
        source: SourcePath,
        seen_whole: u8,
    ) {
        let sum = self.nodes.entry(b).or_insert_with(|| NodeSum {
            e: vec![[0.0; 3]; e.len()],
            dh: [[0.0; 3]; MAX_FUNCTIONS],
            links: Vec::new(),
            link_dh: Vec::new(),
        });
        debug_assert_eq!(sum.e.len(), e.len(), "one node, one set of points");
        let before = sum.link_bytes();
        add_rgb(&mut sum.e, e);
        add_rgb(&mut sum.dh, dh);
        sum.links.push(LinkEntry {
            source,
            seen_whole,
            deviation: deviation.map(|d| d as f32),
        });
        sum.link_dh.extend_from_slice(&dh[..nr]);
        let after = sum.link_bytes();
        self.held.bytes = self.held.bytes + after - before;
        self.held.links += 1;
        self.peak = self.peak.max(self.held);
    }

    /// The node of smallest index with its links, no longer held by the record.
    pub fn pop_first(&mut self) -> Option<(usize, NodeSum)> {
        let (b, sum) = self.nodes.pop_first()?;
        self.held.bytes -= sum.link_bytes();
        self.held.links -= sum.link_count() as u64;
        Some((b, sum))
    }

    /// The per-link entries at their largest so far.
    pub fn peak(&self) -> LinkBytes {
        self.peak
    }
}

/// The links a node gives back: their sources, the children each goes to and how its rays are
/// decided there (seen whole in a child where all its rays from the node's points inside it
/// passed), and their coefficients, in the order they came.
pub(super) struct Resend {
    pub sources: Vec<SourcePath>,
    /// Per link, the children (bit `c` for child `c`) whose points' deviation exceeds the
    /// link's share: those it is sent again to. The others keep its coefficients.
    pub children: Vec<u8>,
    /// Per link, the children where it is taken as seen whole (its `LinkEntry::seen_whole`).
    seen_whole: Vec<u8>,
    /// `nr` per link.
    dh: Vec<Rgb>,
    nr: usize,
}

impl Resend {
    pub fn len(&self) -> usize {
        self.sources.len()
    }

    /// Each link's coefficients (the `nr` it was gathered with), in order.
    pub fn coefficients(&self) -> impl Iterator<Item = &[Rgb]> {
        self.dh.chunks_exact(self.nr)
    }

    /// The links sent again to child `c`, in order: each one's index among those given back,
    /// and the link, taken as seen whole ([`Rays::AllPass`]) where all its rays from the
    /// node's points inside `c` passed, traced otherwise.
    pub fn links_to(&self, c: usize) -> impl Iterator<Item = (usize, Link)> + '_ {
        debug_assert!(c < 4);
        (0..self.len())
            .filter(move |&i| self.children[i] & (1 << c) != 0)
            .map(move |i| {
                let rays = if self.seen_whole[i] & (1 << c) != 0 {
                    Rays::AllPass
                } else {
                    Rays::Trace
                };
                let path = self.sources[i];
                (i, Link { path, rays })
            })
    }
}

impl NodeSum {
    /// When the sum's `deviation` (the oracle's error of a set of point values against a
    /// projection) exceeds `allowed`, the links that must go to the node's children: every link
    /// whose own deviation exceeds its share `allowed / n` in some child, sent again to the
    /// children where it does. What stays (the links kept, and the others' coefficients in the
    /// children where they are within their share) sums to a deviation within `allowed` in
    /// every child, since the deviation of a sum is at most the sum of the deviations. `None`
    /// when the sum passes.
    pub fn links_to_resend(
        self,
        allowed: f64,
        deviation: impl Fn(&[Rgb], &[Rgb; MAX_FUNCTIONS]) -> f64,
    ) -> Option<Resend> {
        if deviation(&self.e, &self.dh) <= allowed {
            return None;
        }
        let n = self.links.len();
        let nr = self.link_dh.len().checked_div(n).unwrap_or(0);
        let share = allowed / n as f64;
        let mut resend = Resend {
            sources: Vec::new(),
            children: Vec::new(),
            seen_whole: Vec::new(),
            dh: Vec::new(),
            nr,
        };
        for (l, dh) in self.links.iter().zip(self.link_dh.chunks_exact(nr.max(1))) {
            let children = (0..4)
                .filter(|&c| f64::from(l.deviation[c]) > share)
                .fold(0u8, |m, c| m | 1 << c);
            if children != 0 {
                resend.sources.push(l.source);
                resend.dh.extend_from_slice(dh);
                resend.children.push(children);
                resend.seen_whole.push(l.seen_whole);
            }
        }
        // Empty only by rounding (the sum's deviation is at most the links' sum): nothing to do.
        (!resend.sources.is_empty()).then_some(resend)
    }
}

/// Rebuilds a shot's parts from their paths, by the shot's own `children` from the part its
/// recursion started from (so each is the part the recursion had). Keeps the children met along
/// the last path: a node's links come in the recursion's order, so consecutive paths share their
/// beginnings.
pub(super) struct Parts<'a, S: Shot> {
    shot: &'a S,
    root: &'a S::Part,
    /// `levels[i]`: the path of the part after `i` splits on the last path, and its children.
    levels: Vec<(SourcePath, [S::Part; 4])>,
}

impl<'a, S: Shot> Parts<'a, S> {
    pub fn new(shot: &'a S, root: &'a S::Part) -> Self {
        Parts {
            shot,
            root,
            levels: Vec::new(),
        }
    }

    /// The part at `path`.
    pub fn get(&mut self, path: SourcePath) -> &S::Part {
        let d = path.depth();
        if d == 0 {
            return self.root;
        }
        let mut keep = 0;
        while keep < self.levels.len()
            && keep < d as usize
            && self.levels[keep].0 == path.prefix(keep as u32)
        {
            keep += 1;
        }
        self.levels.truncate(keep);
        for level in keep as u32..d {
            let children = {
                let parent = match level {
                    0 => self.root,
                    _ => &self.levels[level as usize - 1].1[path.step(level - 1)],
                };
                self.shot.children(parent)
            };
            self.levels.push((path.prefix(level), children));
        }
        &self.levels[d as usize - 1].1[path.step(d - 1)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle's deviation for a constant basis: the largest |value - coefficient| (channel 0).
    fn constant_deviation(e: &[Rgb], dh: &[Rgb; MAX_FUNCTIONS]) -> f64 {
        e.iter()
            .map(|v| (v[0] - dh[0][0]).abs())
            .fold(0.0, f64::max)
    }

    fn link(values: &[f64]) -> (Vec<Rgb>, [Rgb; MAX_FUNCTIONS]) {
        let e: Vec<Rgb> = values.iter().map(|&v| [v, 0.0, 0.0]).collect();
        let mut dh = [[0.0; 3]; MAX_FUNCTIONS];
        dh[0][0] = values.iter().sum::<f64>() / values.len() as f64;
        (e, dh)
    }

    /// A distinct path for link `i` (its first splits spell `i` in base 4).
    fn path(i: usize) -> SourcePath {
        let mut p = SourcePath::ROOT;
        let mut k = i;
        for _ in 0..6 {
            p = p.child(k % 4);
            k /= 4;
        }
        p
    }

    fn index(p: SourcePath) -> usize {
        (0..p.depth()).rev().fold(0, |i, l| i * 4 + p.step(l))
    }

    fn add(r: &mut ShotRecord<()>, b: usize, values: &[f64], i: usize) {
        let (e, dh) = link(values);
        r.add(b, &e, &dh, 1, [constant_deviation(&e, &dh); 4], path(i), 0);
    }

    fn resent(sum: NodeSum, allowed: f64) -> Option<Vec<usize>> {
        sum.links_to_resend(allowed, constant_deviation)
            .map(|r| r.sources.iter().map(|&p| index(p)).collect())
    }

    #[test]
    fn sums_are_the_sums_of_the_links() {
        let mut r = ShotRecord::default();
        for (i, v) in [[1.0, 2.0], [0.5, 0.0], [3.0, 3.0]].iter().enumerate() {
            add(&mut r, 7, v, i);
        }
        let s = &r.nodes[&7];
        assert_eq!(s.links.len(), 3);
        assert_eq!(s.e, vec![[4.5, 0.0, 0.0], [5.0, 0.0, 0.0]]);
        assert!((s.dh[0][0] - (1.5 + 0.25 + 3.0)).abs() < 1e-12);
    }

    #[test]
    fn links_that_each_pass_can_fail_together_and_the_kept_ones_pass() {
        // Ten links, each a step of 0.1 across the node: each deviates by 0.05, the sum by 0.5.
        let mut r = ShotRecord::default();
        for i in 0..10 {
            add(&mut r, 0, &[0.1, 0.0], i);
        }
        // One smooth link stays whatever the budget.
        add(&mut r, 0, &[1.0, 1.0], 10);
        let (_, sum) = r.pop_first().expect("recorded");
        let allowed = 0.2;
        assert!(sum
            .links
            .iter()
            .all(|l| l.deviation.iter().all(|&d| f64::from(d) <= allowed)));
        let sent = resent(sum, allowed).expect("the sum fails");
        assert_eq!(sent, (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn a_link_goes_again_only_to_the_children_where_it_errs() {
        // Ten links whose sum fails; link 3 errs in child 1 only, the others in all.
        let mut r = ShotRecord::<()>::default();
        for i in 0..10 {
            let (e, dh) = link(&[0.1, 0.0]);
            let d = constant_deviation(&e, &dh);
            let deviation = if i == 3 { [0.0, d, 0.0, 0.0] } else { [d; 4] };
            r.add(0, &e, &dh, 1, deviation, path(i), 0);
        }
        let (_, sum) = r.pop_first().expect("recorded");
        let resend = sum
            .links_to_resend(0.2, constant_deviation)
            .expect("the sum fails");
        assert_eq!(resend.len(), 10);
        for (&p, &children) in resend.sources.iter().zip(&resend.children) {
            let expected = if index(p) == 3 { 0b0010 } else { 0b1111 };
            assert_eq!(children, expected, "link {}", index(p));
        }
    }

    #[test]
    fn a_passing_sum_keeps_its_links() {
        let mut r = ShotRecord::default();
        for i in 0..3 {
            add(&mut r, 0, &[0.1, 0.0], i);
        }
        let (_, sum) = r.pop_first().expect("recorded");
        assert!(resent(sum, 0.2).is_none());
    }

    #[test]
    fn what_stays_is_within_the_budget() {
        // Links of random steps: whatever is kept sums to a deviation within the budget.
        let mut next = crate::shuffle::uniform_sequence(12345);
        for _ in 0..200 {
            let mut r = ShotRecord::default();
            let n = 2 + (next() * 20.0) as usize;
            let mut all = Vec::new();
            for i in 0..n {
                let values = [next(), next() * 0.1, next() * 0.01];
                add(&mut r, 0, &values, i);
                all.push((values, i));
            }
            let (_, sum) = r.pop_first().expect("recorded");
            let allowed = next() * 2.0;
            let resend = resent(sum, allowed).unwrap_or_default();
            let mut kept = ShotRecord::default();
            for (values, i) in all.into_iter().filter(|l| !resend.contains(&l.1)) {
                add(&mut kept, 0, &values, i);
            }
            if let Some(k) = kept.nodes.get(&0) {
                assert!(constant_deviation(&k.e, &k.dh) <= allowed + 1e-12);
            }
        }
    }

    #[test]
    fn resent_links_carry_the_coefficients_they_were_gathered_with() {
        let mut r = ShotRecord::<()>::default();
        let nr = 4;
        for i in 0..5 {
            let e = vec![[i as f64, 0.0, 0.0]; 3];
            let mut dh = [[0.0; 3]; MAX_FUNCTIONS];
            for (a, c) in dh.iter_mut().enumerate() {
                *c = [(10 * i + a) as f64, 0.5, -1.0];
            }
            // Links 1 and 3 deviate: they go back; all of link 3's rays passed.
            let deviation = if i % 2 == 1 { 1.0 } else { 0.0 };
            let seen_whole = if i == 3 { 0b1111 } else { 0 };
            r.add(2, &e, &dh, nr, [deviation; 4], path(i), seen_whole);
        }
        let (_, sum) = r.pop_first().expect("recorded");
        let resend = sum.links_to_resend(0.5, |_, _| 1.0).expect("fails");
        assert_eq!(resend.len(), 2);
        for (c, links) in (0..4).map(|c| (c, resend.links_to(c).collect::<Vec<_>>())) {
            let got: Vec<(usize, Rays)> = links
                .iter()
                .map(|&(_, l)| (index(l.path), l.rays))
                .collect();
            // A link whose rays all passed is taken as seen whole in every child.
            assert_eq!(got, [(1, Rays::Trace), (3, Rays::AllPass)], "child {c}");
        }
        for (&p, dh) in resend.sources.iter().zip(resend.coefficients()) {
            let i = index(p);
            let want: Vec<Rgb> = (0..nr).map(|a| [(10 * i + a) as f64, 0.5, -1.0]).collect();
            assert_eq!(dh, want);
        }
    }

    #[test]
    fn a_link_goes_as_seen_whole_only_to_the_children_where_its_rays_passed() {
        // Two links whose sum fails, each erring in children 0, 1 and 2; link 0's rays passed
        // from the node's points in children 0 and 3, link 1's in child 1.
        let mut r = ShotRecord::<()>::default();
        for (i, seen_whole) in [(0, 0b1001), (1, 0b0010)] {
            let (e, dh) = link(&[1.0, 0.0]);
            r.add(0, &e, &dh, 1, [0.5, 0.5, 0.5, 0.0], path(i), seen_whole);
        }
        let (_, sum) = r.pop_first().expect("recorded");
        let resend = sum
            .links_to_resend(0.1, constant_deviation)
            .expect("the sum fails");
        let sent = |c: usize| -> Vec<(usize, Rays)> {
            resend
                .links_to(c)
                .map(|(i, l)| {
                    assert_eq!(resend.sources[i], l.path, "the index is the link's");
                    (index(l.path), l.rays)
                })
                .collect()
        };
        assert_eq!(sent(0), [(0, Rays::AllPass), (1, Rays::Trace)]);
        assert_eq!(sent(1), [(0, Rays::Trace), (1, Rays::AllPass)]);
        assert_eq!(sent(2), [(0, Rays::Trace), (1, Rays::Trace)]);
        // Child 3 keeps both links' coefficients, though link 0 passed there.
        assert_eq!(sent(3), []);
    }

    #[test]
    fn a_recorded_link_costs_its_path_deviation_and_coefficients_whatever_the_part() {
        // The record must not grow with what a source is (a shooter's element is hundreds of
        // bytes): per link, a path, a deviation and the receiver's coefficients, plus the
        // vectors' spare capacity (at most as much again). Point values are per node.
        for nr in [1, 3, 4, 6, 9] {
            let mut r = ShotRecord::<[u8; 4096]>::default();
            r.start_from(&[0; 4096]);
            let e = vec![[1.0; 3]; 13];
            let dh = [[1.0; 3]; MAX_FUNCTIONS];
            let links = 10_000;
            for i in 0..links {
                r.add(i % 7, &e, &dh, nr, [0.0; 4], path(i % 4096), 0);
            }
            let per_link = (LINK_ENTRY_BYTES + nr * size_of::<Rgb>()) as u64;
            let within = |held: LinkBytes| {
                held.bytes >= per_link * held.links && held.bytes <= 2 * per_link * held.links
            };
            assert_eq!(r.held.links, links as u64);
            assert!(within(r.held), "nr {nr}: {:?}", r.held);
            let peak = r.peak();
            assert!(within(peak), "nr {nr}: peak {peak:?}");
            assert!(peak.bytes >= r.held.bytes);
            while r.pop_first().is_some() {}
            assert_eq!(r.held, LinkBytes::default());
            assert_eq!(r.peak(), peak);
        }
    }

    #[test]
    fn source_paths_spell_their_splits() {
        let p = SourcePath::ROOT.child(2).child(0).child(3);
        assert_eq!(p.depth(), 3);
        assert_eq!([p.step(0), p.step(1), p.step(2)], [2, 0, 3]);
        assert_eq!(p.prefix(1), SourcePath::ROOT.child(2));
        assert_eq!(p.prefix(0), SourcePath::ROOT);
        let mut deep = SourcePath::ROOT;
        for _ in 0..SourcePath::MAX_SPLITS {
            deep = deep.child(3);
        }
        assert_eq!(deep.depth(), SourcePath::MAX_SPLITS);
        assert_eq!(deep.prefix(2), SourcePath::ROOT.child(3).child(3));
    }

    /// A shot whose parts are their own paths' digits, to check `Parts` against the recursion.
    struct Digits;

    impl Shot for Digits {
        type Part = Vec<usize>;
        type Source<'s>
            = crate::solver::source::LightSource<'s>
        where
            Self: 's;

        fn source<'s>(&'s self, _: &'s Vec<usize>, _: Rgb) -> Option<Self::Source<'s>> {
            None
        }

        fn verdict_key(&self, _: &Vec<usize>) -> Option<(usize, SourcePath)> {
            None
        }

        fn children(&self, part: &Vec<usize>) -> [Vec<usize>; 4] {
            std::array::from_fn(|c| {
                let mut v = part.clone();
                v.push(c);
                v
            })
        }
    }

    #[test]
    fn parts_are_rebuilt_from_their_paths_in_any_order() {
        let root = vec![];
        let mut parts = Parts::new(&Digits, &root);
        for steps in [
            vec![],
            vec![1, 2, 3],
            vec![1, 2, 0],
            vec![1],
            vec![3, 3, 3, 3, 3, 3, 3, 3, 3],
            vec![1, 2, 3],
            vec![0, 0],
        ] {
            let p = steps.iter().fold(SourcePath::ROOT, |p, &c| p.child(c));
            assert_eq!(parts.get(p), &steps);
        }
    }
}

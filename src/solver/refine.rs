//! The recursion of one shot onto one receiver, after RenderPark's `Refine`: evaluate the
//! interaction (`transfer::receive`), get a verdict (`oracle::evaluate`), act on it (gather the
//! link, split the source, or split the receiver and recurse). [`Shot`] is what shoots (the
//! elements of a root, or a punctual light); [`ShotContext`] what every shot shares (tables,
//! visibility, threshold, counters).
//!
//! Invariant: a link is gathered (and counted) exactly once, at the node the verdict accepts it
//! on; the node-sum check (`node_sums.rs`) takes back exactly what `gather` added.

use super::basis::MAX_FUNCTIONS;
use super::element::Sphere;
use super::hierarchy::Hierarchy;
use super::near_verdicts::{KnownVerdicts, LinkKey, VerdictBudget};
use super::node_reflectance;
use super::oracle::{self, oracle_weight, Verdict};
use super::rules::{corner_probe_points, Bases, BasisAtControlPoints, Rules};
use super::shot_record::{LinkBytes, ShotRecord, SourcePath};
use super::source::{Rays, ReceiverNode, Source};
use super::striped_count::StripedCount;
use super::transfer::{self, Received};
use super::visibility::Visibility;
use super::Quantity;
use crate::domain::{ElementRoot, ElementStatus};
use crate::scene::Rgb;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

/// What shoots in one shot.
pub(super) trait Shot: Sync {
    /// What the recursion splits and records: an element of the shooter (`()` for a light).
    type Part: Clone + Send + Sync;
    /// A part as a receiver node sees it.
    type Source<'s>: Source
    where
        Self: 's;

    /// `part` as a source seen by a receiver node whose oracle weighs channels by `weight`;
    /// `None` when it sends nothing (no unshot radiosity, or an empty element).
    fn source<'s>(&'s self, part: &'s Self::Part, weight: Rgb) -> Option<Self::Source<'s>>;

    /// The four children of a part the oracle split.
    fn children(&self, part: &Self::Part) -> [Self::Part; 4];

    /// The shooter root and the part's path under it, when the part's near links keep their
    /// rays' verdicts for the root's next shots (`near_verdicts.rs`): an indirect shot's
    /// elements; `None` for a direct shot (an emitter's emission is shot once) and a light.
    fn verdict_key(&self, part: &Self::Part) -> Option<(usize, SourcePath)>;
}

/// What every shot of a solve shares.
#[derive(Clone, Copy)]
pub(super) struct ShotContext<'a> {
    pub roots: &'a [ElementRoot],
    pub bases: &'a Bases,
    pub rules: &'a Rules,
    pub psi: &'a BasisAtControlPoints,
    /// Record every gathered link, with its light at the receiver's check points, and judge each
    /// receiver node on the sum of its links after the shot (`refine_by_node_sums`).
    pub node_sums: bool,
    /// Evaluate the links a split gives (four, or a node's re-sends) in parallel before acting
    /// on them in order (`ShotContext::transfer_all`): a direct shot, whose largest receivers
    /// would each hold one core while the others have finished.
    pub split_in_parallel: bool,
    pub visibility: &'a Visibility,
    /// Absolute error threshold, in W (sum over channels).
    pub threshold: f64,
    /// The lowest threshold the node-sum check holds a node to where its light's detail is not
    /// within [`DETAIL_REL`](super::DETAIL_REL) of its brightest point (`node_sums.rs`):
    /// `threshold / DIRECT_DETAIL_TIGHTENING` in direct shots (sharp shadow limits), `threshold`
    /// in the others.
    pub detail_threshold: f64,
    pub min_edge: f64,
    pub quantity: Quantity,
    pub links: &'a StripedCount,
    pub capped: &'a AtomicU64,
    pub touching: &'a AtomicU64,
    pub node_sum_splits: &'a AtomicU64,
    /// The largest link record of any receiver in any shot (`ShotRecord::peak`).
    pub link_records: &'a Mutex<LinkBytes>,
    pub cancel: &'a AtomicBool,
    /// When the time budget ends (`SolverParams::max_seconds`): a pass still running then takes
    /// no further piece of receivers (`pass::shoot`).
    pub deadline: Option<std::time::Instant>,
    /// Each root's bounding sphere (`far_field.rs`).
    pub spheres: &'a [Sphere],
    /// Each root's far-link point (`far_field::link_point`).
    pub link_points: &'a [DVec3],
    /// The bytes the receivers' kept near-link verdicts may take (`near_verdicts.rs`).
    pub near_verdicts: &'a VerdictBudget,
}

impl ShotContext<'_> {
    /// Has the time budget ended?
    pub fn past_deadline(&self) -> bool {
        self.deadline
            .is_some_and(|d| std::time::Instant::now() >= d)
    }

    /// Transfers `part` of `shot` to receiver node `b` of `rcv` (root `rcv_index`), its shadow
    /// rays decided as `rays` says, refining as the oracle asks.
    #[allow(clippy::too_many_arguments)]
    pub fn transfer<S: Shot>(
        &self,
        shot: &S,
        part: &S::Part,
        rcv_index: usize,
        rcv: &mut Hierarchy,
        b: usize,
        record: &mut ShotRecord<S::Part>,
        rays: Rays,
    ) {
        if self.node_sums {
            // Recorded links name their sources by the splits that lead to them from `part`.
            record.start_from(part);
        }
        let link = Link {
            path: SourcePath::ROOT,
            rays,
        };
        self.transfer_at(shot, part, link, rcv_index, rcv, b, record);
    }

    /// [`ShotContext::transfer`] of the part at `link.path` under the part the record started
    /// from, its shadow rays decided as `link.rays` says, on a fully covered or native node (an
    /// extended root's other nodes trace), and so those of the source's parts if the oracle
    /// splits the source; the node's children trace if it splits the node (on one ray per point,
    /// [`Rays::Centre`], they keep it).
    #[allow(clippy::too_many_arguments)]
    pub fn transfer_at<S: Shot>(
        &self,
        shot: &S,
        part: &S::Part,
        link: Link,
        rcv_index: usize,
        rcv: &mut Hierarchy,
        b: usize,
        record: &mut ShotRecord<S::Part>,
    ) {
        // Nothing acts between the evaluation and the action: the oracle judges at once.
        if let Some(evaluation) = self.evaluate(shot, part, link, rcv_index, rcv, b, true) {
            self.act(shot, part, evaluation, rcv_index, rcv, b, record);
        }
    }

    /// [`ShotContext::transfer_at`] of every `(part, link, node)` of `links`, in order. When
    /// `split_in_parallel`, what each link delivers is computed first, in parallel, reading
    /// nothing an action changes; then, link by link in order, the oracle's verdict and the
    /// action. The result is the one of `transfer_at` link after link, whatever the threads
    /// (`tests/reproducible.rs`).
    pub fn transfer_all<S: Shot>(
        &self,
        shot: &S,
        links: &[(&S::Part, Link, usize)],
        rcv_index: usize,
        rcv: &mut Hierarchy,
        record: &mut ShotRecord<S::Part>,
    ) {
        if !self.split_in_parallel || links.len() < 2 {
            for &(part, link, b) in links {
                self.transfer_at(shot, part, link, rcv_index, rcv, b, record);
            }
            return;
        }
        let read: &Hierarchy = rcv;
        let evaluations: Vec<Option<Evaluation>> = links
            .par_iter()
            .map(|&(part, link, b)| self.evaluate(shot, part, link, rcv_index, read, b, false))
            .collect();
        for (&(part, _, b), evaluation) in links.iter().zip(evaluations) {
            if let Some(evaluation) = evaluation {
                self.act(shot, part, evaluation, rcv_index, rcv, b, record);
            }
        }
    }

    /// What `part` delivers to receiver node `b` through `link` (the costly part: rays and form
    /// factors), and with `judge` the oracle's verdict on the node as it is; `None` when it
    /// sends nothing (or the solve was cancelled). Reads the receiver only (but for the cache of
    /// its spread points' stand-ins, `ReceiverNode::spread_point`).
    #[allow(clippy::too_many_arguments)]
    fn evaluate<S: Shot>(
        &self,
        shot: &S,
        part: &S::Part,
        link: Link,
        rcv_index: usize,
        rcv: &Hierarchy,
        b: usize,
        judge: bool,
    ) -> Option<Evaluation> {
        if self.cancel.load(Ordering::Relaxed) {
            return None;
        }
        let rroot = &self.roots[rcv_index];
        let weight = oracle_weight(self.quantity, node_reflectance::rho_of(rcv, rroot, b));
        let source = shot.source(part, weight)?;
        let receiver = ReceiverNode::new(rroot, rcv, b, self.rules);
        let rays = match (link.rays, &receiver.cover) {
            // Off the face, a node's points cast from stand-ins on the face's border, which
            // the rays of the node the link was re-sent from need not have sampled.
            (Rays::AllPass, Some(c)) if c.status != ElementStatus::Full => Rays::Trace,
            (rays, _) => rays,
        };
        // A link whose rays a shot of the same root traced before reads their verdicts back.
        let key = shot
            .verdict_key(part)
            .filter(|_| rays != Rays::AllPass)
            .map(|(s, path)| LinkKey::new(s, path, b, rays == Rays::Centre));
        let known = key.and_then(|k| rcv.near_verdicts.known(&k));
        let received = Box::new(self.receive(&source, &receiver, rays, known.as_ref()));
        let verdict =
            judge.then(|| oracle::evaluate(self, &source, &receiver, &received, weight, rays));
        Some(Evaluation {
            path: link.path,
            rays,
            received,
            verdict,
            key,
        })
    }

    /// Asks the oracle about a link of `part` to node `b` (the node as it is now: whether it is
    /// still a leaf weighs a textured receiver's reflectance), and acts on the verdict: gathers
    /// the link, or splits the source or the node and transfers the pieces.
    #[allow(clippy::too_many_arguments)]
    fn act<S: Shot>(
        &self,
        shot: &S,
        part: &S::Part,
        evaluation: Evaluation,
        rcv_index: usize,
        rcv: &mut Hierarchy,
        b: usize,
        record: &mut ShotRecord<S::Part>,
    ) {
        let rroot = &self.roots[rcv_index];
        let Evaluation {
            path,
            rays,
            received,
            verdict,
            key,
        } = evaluation;
        let verdict = if let Some(verdict) = verdict {
            verdict
        } else {
            let weight = oracle_weight(self.quantity, node_reflectance::rho_of(rcv, rroot, b));
            let Some(source) = shot.source(part, weight) else {
                return;
            };
            let receiver = ReceiverNode::new(rroot, rcv, b, self.rules);
            oracle::evaluate(self, &source, &receiver, &received, weight, rays)
        };
        if let Some(key) = key {
            let points = received.points;
            let seen = (&received.seen[..points], &received.form_factors[..points]);
            let verdict_rays = received.verdict_rays.get();
            rcv.near_verdicts
                .keep(key, seen, verdict_rays, self.near_verdicts);
        }
        match verdict {
            Verdict::Accept => self.accept(path, rroot, rcv, b, &received, record),
            Verdict::Capped => {
                self.capped.fetch_add(1, Ordering::Relaxed);
                self.accept(path, rroot, rcv, b, &received, record);
            }
            Verdict::SplitSource => {
                let children = shot.children(part);
                let links: [_; 4] = std::array::from_fn(|c| {
                    let sub = Link {
                        path: path.child(c),
                        rays,
                    };
                    (&children[c], sub, b)
                });
                self.transfer_all(shot, &links, rcv_index, rcv, record);
            }
            Verdict::SplitReceiver => {
                let first = self.first_child(rcv, b, rroot);
                // The node's children trace: rays taken as passing stand for one level. A link on
                // one ray per point stays so: its children carry less still.
                let link = Link {
                    path,
                    rays: if rays == Rays::Centre {
                        Rays::Centre
                    } else {
                        Rays::Trace
                    },
                };
                let links: [_; 4] = std::array::from_fn(|c| (part, link, first + c));
                self.transfer_all(shot, &links, rcv_index, rcv, record);
            }
        }
    }

    /// The source's irradiance at the receiver's rule points, and at its check points when the
    /// node sums are judged; an earlier shot's verdicts read back where they are `known`.
    fn receive(
        &self,
        source: &impl Source,
        receiver: &ReceiverNode,
        rays: Rays,
        known: Option<&KnownVerdicts>,
    ) -> Received {
        let shape = receiver.root.shape;
        let check_points = if self.node_sums {
            corner_probe_points(shape).len()
        } else {
            0
        };
        let received = transfer::receive(
            source,
            receiver,
            self.rules.of(shape),
            self.psi.of(shape),
            self.psi.children_of(shape),
            self.bases.of(shape).len(),
            check_points,
            rays,
            known,
        );
        if received.touching > 0 {
            self.touching
                .fetch_add(received.touching, Ordering::Relaxed);
        }
        received
    }

    /// Gathers an accepted link at node `b` (and records it for the node-sum check: its values
    /// go to the node's sums, the link keeps its source's path, its deviation and coefficients).
    fn accept<P>(
        &self,
        path: SourcePath,
        rroot: &ElementRoot,
        rcv: &mut Hierarchy,
        b: usize,
        received: &Received,
        record: &mut ShotRecord<P>,
    ) {
        let nr = rcv.len;
        self.links.add(1);
        gather(rcv, b, &received.dh[..nr]);
        if self.node_sums {
            let e = &received.e[..received.points];
            let deviation = self.node_sum_child_deviation(rroot)(e, &received.dh);
            record.add(b, e, &received.dh, nr, deviation, path, received.seen_whole);
        }
    }

    /// Accepts a far link (`far_field.rs`): a constant irradiance `e` over `root`, added to
    /// every node at once where the reflectance is constant ([`Hierarchy::add_constant`], no
    /// push-pull of the whole tree per far link), else gathered at the root node for the shot's
    /// push-pull. Whether it added light: a blocked link (`e` zero) is counted and adds nothing,
    /// so the receiver's power stands.
    pub fn accept_far(
        &self,
        rcv: &mut Hierarchy,
        root: &ElementRoot,
        e: Rgb,
        direct: bool,
    ) -> bool {
        self.links.add(1);
        if e == [0.0; 3] {
            return false;
        }
        if rcv.reflectance.is_empty() {
            rcv.add_constant(e, root.rho, direct);
            return true;
        }
        let mut dh = [[0.0; 3]; MAX_FUNCTIONS];
        dh[0] = e;
        gather(rcv, 0, &dh[..rcv.len]);
        true
    }

    /// The first of node `b`'s four children, splitting `b` first if it is a leaf (the new
    /// children get their side tables: covers, spread points' cells, reflectance).
    pub fn first_child(&self, rcv: &mut Hierarchy, b: usize, root: &ElementRoot) -> usize {
        if rcv.nodes[b].is_leaf() {
            rcv.split_element(b, root, self.bases.of(root.shape), &self.rules.cover)
        } else {
            rcv.nodes[b].first_child as usize
        }
    }
}

/// A link evaluated: where its part lies, how its rays were decided, what it delivered, the
/// oracle's verdict when it was judged at once (`None`: to be judged when acted on), and the key
/// its rays' verdicts are kept under when its shot keeps them.
struct Evaluation {
    path: SourcePath,
    rays: Rays,
    received: Box<Received>,
    verdict: Option<Verdict>,
    key: Option<LinkKey>,
}

/// A link of a shot's recursion: where its part lies under the part the recursion started from,
/// and how its shadow rays are decided.
#[derive(Debug, Clone, Copy)]
pub(super) struct Link {
    pub path: SourcePath,
    pub rays: Rays,
}

/// Adds an accepted link's coefficients to node `b`'s gathered irradiance.
pub(super) fn gather(rcv: &mut Hierarchy, b: usize, dh: &[Rgb]) {
    add_to_gathered(rcv, b, dh, 1.0);
    rcv.touched = true;
}

/// Removes a link's coefficients from node `b`'s gathered irradiance: exactly what `gather` added.
pub(super) fn take_back(rcv: &mut Hierarchy, b: usize, dh: &[Rgb]) {
    add_to_gathered(rcv, b, dh, -1.0);
}

fn add_to_gathered(rcv: &mut Hierarchy, b: usize, dh: &[Rgb], sign: f64) {
    let nr = dh.len();
    debug_assert!(nr <= MAX_FUNCTIONS);
    for (a, d) in dh.iter().enumerate() {
        for ch in 0..3 {
            rcv.dh[b * nr + a][ch] += sign * d[ch];
        }
    }
}

//! The solver: hierarchical multi-wavelet radiosity by progressive shooting.
//!
//! Owns the element hierarchies of every root, the transfer of light between elements (quadrature
//! with the exact point-to-polygon form factor for the constant part, visibility by rays), the
//! refinement oracle and the shooting loop. It does no I/O and knows neither glTF nor HTTP.
//!
//! Shooting (DESIGN.md 5.1): emitters first shoot their emission (the "direct" shots, recorded
//! apart so `--indirect-only` can leave them out); then the root with the most unshot power shoots
//! until `unshot_ratio = unshot power / emitted power <= target`. Links are not cached: each
//! transfer is recomputed when its source shoots again (memory stays proportional to elements).
//! Receivers of one shot are processed in parallel (rayon); the shooter is read-only during it,
//! and is refined only virtually (sub-elements computed by push, not stored).

pub mod basis;
pub mod cover;
pub mod hierarchy;
pub mod kernel;
pub mod lights;
pub mod node_reflectance;
mod node_sums;
pub mod quadrature;
mod shooting;
mod shot_record;
mod solution;
pub use shooting::solve;
pub mod visibility;

use crate::domain::{ElementRoot, ElementStatus, Shape};
use crate::scene::{PunctualLight, Rgb};
use basis::{child_maps, Basis, ChildMap, MAX_FUNCTIONS};
use cover::{face_integral, node_box, CoverRules, NodeCover};
use glam::{DVec2, DVec3};
use hierarchy::Hierarchy;
use quadrature::{rule, zones_of_influence, QuadPoint};
use rayon::prelude::*;
use shot_record::ShotRecord;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;
use visibility::Visibility;

/// What lightmaps and probes hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// `L = B / pi`, emission included.
    Radiance,
    /// `H / pi`, emission not included.
    Irradiance,
}

/// Default refinement tolerance: a transfer is refined while its estimated error exceeds this
/// fraction of the scene's emitted power. Chosen against the Monte Carlo references
/// (`tests/reference.rs`, README): at M2, 2e-6 takes the Red Eclipse level from 5.6 % (1e-5) to
/// 2.85 % and the Kenney building from 5.9 % to 3.5 %, at 2-4x the time; 1e-6 gains little more
/// on the building (3.2 %) for twice the time again (measured with the node-sum check after
/// direct shots only; after every shot, the default gives 2.64 % and 3.29 %).
pub const DEFAULT_TOLERANCE: f64 = 2e-6;
/// Deepest subdivision of an element (4^depth sub-elements at most).
pub const MAX_DEPTH: u8 = 9;
/// Elements are not split below this edge length, relative to the scene diagonal.
pub const MIN_EDGE_REL: f64 = 1e-3;
/// Safety limit on shots (a closed scene of rho = 1 never converges).
pub const DEFAULT_MAX_ITERATIONS: u64 = 1_000_000;

/// Solver settings (the CONTRACT's solver options that reach the solver).
#[derive(Debug, Clone)]
pub struct SolverParams {
    pub order: usize,
    pub target_unshot: f64,
    pub tolerance: f64,
    pub max_seconds: Option<f64>,
    pub quantity: Quantity,
    pub indirect_only: bool,
    pub max_iterations: u64,
    /// After each shot, judge every receiver node on the sum of the links it gathered and
    /// refine where that sum is not represented within the tolerance (`refine_by_node_sums`).
    /// On by default; off gives the per-link oracle alone (`tests/solver.rs` compares both).
    pub node_sums: bool,
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            order: 2,
            target_unshot: 1e-3,
            tolerance: DEFAULT_TOLERANCE,
            max_seconds: None,
            quantity: Quantity::Radiance,
            indirect_only: false,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            node_sums: true,
        }
    }
}

/// Why the shooting loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    Converged,
    TimeBudget,
    Cancelled,
    IterationLimit,
}

impl StopReason {
    pub fn as_str(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::TimeBudget => "time_budget",
            StopReason::Cancelled => "cancelled",
            StopReason::IterationLimit => "iteration_limit",
        }
    }
}

/// Progress after a shot (feeds the CLI bar, convergence.csv and the HTTP progress object).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    pub iterations: u64,
    pub unshot_ratio: f64,
    pub elements: u64,
    pub links: u64,
    pub seconds: f64,
}

/// Counters of rare numerical fallbacks and work done.
#[derive(Debug, Clone, Default)]
pub struct SolveStats {
    pub iterations: u64,
    pub links: u64,
    pub elements: u64,
    pub rays: u64,
    pub seconds: f64,
    pub unshot_ratio: f64,
    pub emitted_power: Rgb,
    pub stop_reason: Option<StopReason>,
    /// Transfers accepted above tolerance because neither side could be split further.
    pub refinement_capped: u64,
    /// Receiver points where no source quadrature point lay in front of the receiver (touching
    /// elements): the exact form factor times the visible fraction stood in for the quadrature.
    pub touching_fallbacks: u64,
    /// Receiver nodes that gave links back to their children after a shot, because the
    /// sum of their links was not represented within the tolerance (`SolverParams::node_sums`).
    pub node_sum_splits: u64,
}

/// The solved scene: roots, their hierarchies, and what it took.
#[derive(Debug)]
pub struct Solution {
    pub roots: Vec<ElementRoot>,
    pub hierarchies: Vec<Hierarchy>,
    pub params: SolverParams,
    pub stats: SolveStats,
    pub convergence: Vec<Progress>,
    bases: Bases,
}

#[derive(Debug, Clone)]
struct Bases {
    triangle: Basis,
    parallelogram: Basis,
}

impl Bases {
    fn new(order: usize) -> Self {
        Bases {
            triangle: Basis::new(Shape::Triangle, order),
            parallelogram: Basis::new(Shape::Parallelogram, order),
        }
    }
    fn of(&self, shape: Shape) -> &Basis {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.parallelogram,
        }
    }
}

/// Quadrature rules per shape at the solver's order.
struct Rules {
    triangle: Vec<QuadPoint>,
    /// The parallelogram rule (`cover.rule`) with its zones of influence.
    cover: CoverRules,
}

impl Rules {
    fn new(order: usize) -> Self {
        Rules {
            triangle: rule(Shape::Triangle, order + 1),
            cover: CoverRules {
                rule: rule(Shape::Parallelogram, order + 1),
                zones: zones_of_influence(order + 1),
                moment_rule: rule(Shape::Triangle, 3),
            },
        }
    }
    fn of(&self, shape: Shape) -> &[QuadPoint] {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.cover.rule,
        }
    }
}

/// Each shape's basis functions at its rule's points (the receiver's control points), then at its
/// corner probe points.
pub(super) struct BasisAtControlPoints {
    triangle: Vec<[f64; MAX_FUNCTIONS]>,
    parallelogram: Vec<[f64; MAX_FUNCTIONS]>,
}

impl BasisAtControlPoints {
    fn new(bases: &Bases, rules: &Rules) -> Self {
        let at = |shape: Shape| {
            rules
                .of(shape)
                .iter()
                .map(|q| q.st)
                .chain(corner_probe_points(shape).iter().copied())
                .map(|st| {
                    let mut phi = [0.0; MAX_FUNCTIONS];
                    bases.of(shape).eval(st, &mut phi);
                    phi
                })
                .collect()
        };
        BasisAtControlPoints {
            triangle: at(Shape::Triangle),
            parallelogram: at(Shape::Parallelogram),
        }
    }
    fn of(&self, shape: Shape) -> &[[f64; MAX_FUNCTIONS]] {
        match shape {
            Shape::Triangle => &self.triangle,
            Shape::Parallelogram => &self.parallelogram,
        }
    }
}

/// The world point that stands in for root point `map(st)` in visibility queries: the point itself
/// on a native root or on the face; else its closest point on the face (`V'(Q,P) = V(Q,P')`).
fn visibility_point(root: &ElementRoot, map: &ChildMap, st: DVec2) -> DVec3 {
    let p = map.apply(st);
    match &root.mask {
        Some(mask) => root.frame.point(mask.closest_point(p)),
        None => root.frame.point(p),
    }
}

/// Where quadrature point `k` (at `st`) of receiver element `patch` of `root` receives light: the
/// point itself, or, off an extended face, its stand-in (`cover.visibility_point`, the closest
/// point on the face), in visibility and kernel alike. The extension is then continuous across the
/// face's border: with the kernel at the point itself, a wall standing on the border inside the
/// domain is seen from behind on one side of it and from the front on the other, and elements
/// straddling the border average the two.
fn receiving_point(
    root: &ElementRoot,
    patch: &Patch,
    cover: Option<&NodeCover>,
    k: usize,
    st: DVec2,
) -> DVec3 {
    match cover {
        Some(c) => root.frame.point(c.visibility_point[k]),
        None => patch.point(st),
    }
}

/// What a source element emits from: its own shape, or the face inside it; on its front side only.
struct Emitter {
    shape: EmitterShape,
    /// A point of the source's plane and its unit normal (the emitting side).
    origin: DVec3,
    normal: DVec3,
}

enum EmitterShape {
    Polygon(Vec<DVec3>),
    Rings(Arc<FaceRings>),
}

/// The face inside a partly covered element, as world-space rings (see `FaceMask::clip`).
type FaceRings = Vec<Vec<DVec3>>;

/// The face rings of element `map` of `root` when the element is partly covered (computed once per
/// source element, not per transfer: clipping is O(n) in the face's edges).
fn partial_face_rings(
    root: &ElementRoot,
    map: &ChildMap,
    cover: Option<&NodeCover>,
) -> Option<Arc<FaceRings>> {
    match (&root.mask, cover) {
        (Some(mask), Some(c)) if c.status == ElementStatus::Partial => {
            Some(world_rings(root, &mask.clip(node_box(map))))
        }
        _ => None,
    }
}

/// Rings in `root`'s `(s,t)` as world-space rings.
fn world_rings(root: &ElementRoot, rings: &[Vec<DVec2>]) -> Arc<FaceRings> {
    Arc::new(
        rings
            .iter()
            .map(|r| r.iter().map(|p| root.frame.point(*p)).collect())
            .collect(),
    )
}

impl Emitter {
    fn new(root: &ElementRoot, patch: &Patch, rings: Option<&Arc<FaceRings>>) -> Self {
        let shape = match rings {
            Some(r) => EmitterShape::Rings(r.clone()),
            None => {
                let mut polygon = Vec::with_capacity(4);
                patch.corners(root.shape, &mut polygon);
                EmitterShape::Polygon(polygon)
            }
        };
        Emitter {
            shape,
            origin: patch.origin,
            normal: root.normal,
        }
    }

    /// Exact unoccluded form factor from a differential area at `x` (normal `n`): zero behind the
    /// source's plane, which a one-sided emitter does not light (a receiver element, or an
    /// extended domain, may reach behind a source it otherwise faces).
    fn form_factor(&self, x: DVec3, n: DVec3) -> f64 {
        if self.normal.dot(x - self.origin) <= 0.0 {
            return 0.0;
        }
        match &self.shape {
            EmitterShape::Polygon(p) => kernel::point_polygon_form_factor(x, n, p),
            EmitterShape::Rings(r) => kernel::point_rings_form_factor(x, n, r),
        }
    }
}

fn mean_rgb_sum(c: Rgb) -> f64 {
    c[0] + c[1] + c[2]
}

/// World geometry of a sub-element given its map in the root's reference coordinates.
#[derive(Debug, Clone, Copy)]
struct Patch {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
    area: f64,
}

impl Patch {
    fn new(root: &ElementRoot, map: &ChildMap) -> Self {
        let f = &root.frame;
        let origin = f.point(map.o);
        let u = f.u * map.e1.x + f.v * map.e1.y;
        let v = f.u * map.e2.x + f.v * map.e2.y;
        let full = u.cross(v).length();
        let area = match root.shape {
            Shape::Triangle => 0.5 * full,
            Shape::Parallelogram => full,
        };
        Patch { origin, u, v, area }
    }
    fn point(&self, st: DVec2) -> DVec3 {
        self.origin + self.u * st.x + self.v * st.y
    }
    fn corners(&self, shape: Shape, out: &mut Vec<DVec3>) {
        out.clear();
        out.push(self.origin);
        out.push(self.origin + self.u);
        if shape == Shape::Parallelogram {
            out.push(self.origin + self.u + self.v);
        }
        out.push(self.origin + self.v);
    }
    fn min_edge(&self) -> f64 {
        self.u.length().min(self.v.length())
    }
}

/// The source of a transfer: an element of the shooter, stored or virtual (computed by push).
#[derive(Clone)]
struct Source {
    map: ChildMap,
    depth: u8,
    /// The shooter's stored node with this map, when there is one.
    node: Option<usize>,
    /// The unshot radiosity shot from this element.
    coeffs: [Rgb; MAX_FUNCTIONS],
    /// Extended shooter only: how the element covers the face.
    cover: Option<NodeCover>,
    /// A partly covered element's face, for its exact form factor.
    rings: Option<Arc<FaceRings>>,
    /// The unshot radiosity's mean over the face inside the element (coefficient 0 unless the
    /// element is partly covered): what the element emits, per unit of face area.
    face_mean: Rgb,
}

impl Source {
    /// `face_mean` of an element whose radiosity is its own `coeffs` (a leaf, or virtual: pushed
    /// from one), from its face moments; `stored`: the stored node's mean over its leaves
    /// (`cover::face_means`).
    fn face_mean(coeffs: &[Rgb], cover: Option<&NodeCover>, stored: Option<Rgb>) -> Rgb {
        match cover {
            Some(c) if c.status == ElementStatus::Partial && c.moments[0] > 0.0 => stored
                .unwrap_or_else(|| {
                    std::array::from_fn(|ch| {
                        coeffs
                            .iter()
                            .zip(&c.moments)
                            .map(|(x, m)| x[ch] * m)
                            .sum::<f64>()
                            / c.moments[0]
                    })
                }),
            _ => coeffs[0],
        }
    }
}

struct ShotContext<'a> {
    roots: &'a [ElementRoot],
    bases: &'a Bases,
    rules: &'a Rules,
    psi: &'a BasisAtControlPoints,
    /// Record every gathered link, with its light at the receiver's check points, and judge each
    /// receiver node on the sum of its links after the shot (`refine_by_node_sums`).
    node_sums: bool,
    visibility: &'a Visibility,
    source_root: usize,
    source_hierarchy: &'a Hierarchy,
    /// A direct shot: the emission alone (a constant), not the shooter's stored unshot.
    direct: bool,
    /// An extended shooter's unshot radiosity, per stored node its mean over the face inside
    /// (`cover::face_means`); `None` for a native shooter or a direct shot.
    source_face_means: Option<&'a [Rgb]>,
    /// Absolute error threshold, in W (sum over channels).
    threshold: f64,
    min_edge: f64,
    quantity: Quantity,
    links: &'a AtomicU64,
    capped: &'a AtomicU64,
    touching: &'a AtomicU64,
    node_sum_splits: &'a AtomicU64,
    cancel: &'a AtomicBool,
}

impl ShotContext<'_> {
    fn source_children(&self, s: &Source) -> [Source; 4] {
        let sroot = &self.roots[self.source_root];
        let shape = sroot.shape;
        let basis = self.bases.of(shape);
        let n = basis.len();
        let maps = child_maps(shape);
        let h = self.source_hierarchy;
        std::array::from_fn(|c| {
            let stored = s
                .node
                .filter(|&node| !h.nodes[node].is_leaf())
                .map(|node| h.nodes[node].first_child as usize + c);
            let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
            match stored {
                Some(child) if !self.direct => coeffs[..n].copy_from_slice(h.coeffs(&h.u, child)),
                _ => basis.push(c, &s.coeffs[..n], &mut coeffs[..n]),
            }
            let map = s.map.then(&maps[c]);
            // A virtual element's face is clipped once, for its moments and its rings.
            let (cover, rings) = match (&sroot.mask, stored) {
                (None, _) => (None, None),
                (Some(_), Some(child)) => {
                    let cover = h.covers[child];
                    (Some(cover), partial_face_rings(sroot, &map, Some(&cover)))
                }
                (Some(mask), None) => {
                    let (cover, face) =
                        NodeCover::with_face(mask, &map, &self.rules.cover, basis, false);
                    (Some(cover), face.map(|f| world_rings(sroot, &f)))
                }
            };
            // (`None` on a direct shot: its constant's face mean is the constant.)
            let stored_mean = stored
                .zip(self.source_face_means)
                .map(|(child, means)| means[child]);
            Source {
                rings,
                face_mean: Source::face_mean(&coeffs[..n], cover.as_ref(), stored_mean),
                map,
                depth: s.depth + 1,
                node: stored,
                coeffs,
                cover,
            }
        })
    }

    /// Transfers the source's unshot radiosity to receiver node `b` of `rcv`, refining as needed.
    fn transfer(
        &self,
        src: &Source,
        rcv_index: usize,
        rcv: &mut Hierarchy,
        b: usize,
        record: &mut ShotRecord<Source>,
    ) {
        if self.cancel.load(Ordering::Relaxed) {
            return;
        }
        let sroot = &self.roots[self.source_root];
        let rroot = &self.roots[rcv_index];
        let sbasis = self.bases.of(sroot.shape);
        let rbasis = self.bases.of(rroot.shape);
        let (ns, nr) = (sbasis.len(), rbasis.len());
        if src.coeffs[..ns].iter().all(|c| c.iter().all(|&x| x == 0.0)) {
            return;
        }
        // Empty elements of an extended domain never emit.
        if src.cover.is_some_and(|c| !c.emits()) {
            return;
        }
        let sp = Patch::new(sroot, &src.map);
        let rnode = rcv.nodes[b];
        let rp = Patch::new(rroot, &rnode.map);
        let rcover = cover::of_node(rcv, rroot, b);
        let emitter = Emitter::new(sroot, &sp, src.rings.as_ref());

        let srule = self.rules.of(sroot.shape);
        let rrule = self.rules.of(rroot.shape);
        let mut phi_s = [[0.0; MAX_FUNCTIONS]; 64];
        let mut ys = [DVec3::ZERO; 64];
        let mut ys_vis = [DVec3::ZERO; 64];
        // Emission weights: the rule's, times the covered fraction of each point's zone.
        let mut alpha = [1.0f64; 64];
        let mut alpha_weight = 0.0;
        for (l, q) in srule.iter().enumerate() {
            sbasis.eval(q.st, &mut phi_s[l]);
            ys[l] = sp.point(q.st);
            ys_vis[l] = ys[l];
            if let Some(c) = &src.cover {
                alpha[l] = c.alpha[l];
                ys_vis[l] = sroot.frame.point(c.visibility_point[l]);
            }
            alpha_weight += alpha[l] * q.weight;
        }
        // The source's radiosity at its rule points. A partly covered source's values are shifted
        // by a constant so that their alpha-weighted mean is its exact mean over the face
        // (`Source::face_mean`): the points keep the variation, the constant carries the face's
        // exact power with the exact form factor. The alpha weights alone miss the face's shape
        // (a sliver of face along the element's border takes the weight of points well inside,
        // where the polynomial differs), and an inner node's polynomial is its projection over
        // the whole element, off-face extension included: unshifted, a Red Eclipse floor's shot
        // delivered 1.6x its unshot power.
        let source_mean = src.face_mean;
        let mut radiosity = [[0.0f64; 3]; 64];
        for (l, b) in radiosity.iter_mut().take(srule.len()).enumerate() {
            for bfn in 0..ns {
                for ch in 0..3 {
                    b[ch] += phi_s[l][bfn] * src.coeffs[bfn][ch];
                }
            }
        }
        let source_partial = src
            .cover
            .is_some_and(|c| c.status == ElementStatus::Partial);
        if source_partial && alpha_weight > 0.0 {
            let mut rule_mean = [0.0; 3];
            for (l, q) in srule.iter().enumerate() {
                for ch in 0..3 {
                    rule_mean[ch] += q.weight * alpha[l] * radiosity[l][ch] / alpha_weight;
                }
            }
            for b in radiosity.iter_mut().take(srule.len()) {
                for ch in 0..3 {
                    b[ch] += source_mean[ch] - rule_mean[ch];
                }
            }
        }
        let ignore = [sroot.face.0, rroot.face.0];
        let oracle_weight = oracle_weight(self.quantity, node_reflectance::rho_of(rcv, rroot, b));
        // The amplitude of the source's non-constant part: what a misplaced emission weight can
        // move (the constant part is exact: it uses the exact form factor).
        let weighted_amplitude = |bfn: usize| {
            (0..3)
                .map(|ch| oracle_weight[ch] * src.coeffs[bfn][ch].abs())
                .sum::<f64>()
        };
        let source_variation: f64 = (1..ns).map(weighted_amplitude).sum();
        // The source's mean radiosity, weighted as the oracle's errors are.
        let source_strength: f64 = (0..3)
            .map(|ch| oracle_weight[ch] * source_mean[ch].abs())
            .sum();
        let mut coverage_err: f64 = 0.0;
        let mut e_k = [[0.0f64; 3]; 64];
        let mut dh = [[0.0f64; 3]; MAX_FUNCTIONS];
        let psi = self.psi.of(rroot.shape);
        let mut any_visible = false;
        let mut any_blocked = false;
        // Partial visibility: the error the source's sampling may cause at a receiver point.
        let mut source_side_err: f64 = 0.0;
        // Unoccluded irradiance at the receiver points, sum over channels weighted as the oracle's.
        let mut unoccluded_max: f64 = 0.0;
        // Unoccluded exchange (area x form factor) seen from the receiver's rule points.
        let mut exchange_seen_by_receiver = 0.0;
        // The rule's points, then check points near the corners: these take no part in the
        // projection or in this link's oracle, only in the node's check after the shot.
        let nk = rrule.len();
        let check_points: &[DVec2] = if self.node_sums {
            corner_probe_points(rroot.shape)
        } else {
            &[]
        };
        for k in 0..nk + check_points.len() {
            let x = match rrule.get(k) {
                Some(q) => receiving_point(rroot, &rp, rcover.as_ref(), k, q.st),
                None => visibility_point(rroot, &rnode.map, check_points[k - nk]),
            };
            let f_exact = emitter.form_factor(x, rroot.normal);
            if f_exact <= 0.0 {
                continue;
            }
            let rule_point = k < nk;
            if let Some(q) = rrule.get(k) {
                let covered = rcover.as_ref().map_or(1.0, |c| c.alpha[k]);
                exchange_seen_by_receiver += q.weight * covered * f_exact * rp.area;
            }
            let unoccluded = f_exact * source_strength;
            if rule_point {
                unoccluded_max = unoccluded_max.max(unoccluded);
            }
            let mut fq = 0.0;
            let mut e = [0.0; 3];
            let mut visible_weight = 0.0;
            let mut front_points = 0usize;
            let (mut front_weight, mut front_visible) = (0.0, 0.0);
            for (l, ql) in srule.iter().enumerate() {
                if alpha[l] <= 0.0 {
                    continue;
                }
                let kxy = kernel::geometric_kernel(x, rroot.normal, ys[l], sroot.normal)
                    * sp.area
                    * ql.weight
                    * alpha[l];
                let vis = self.visibility.visible(x, ys_vis[l], ignore);
                if vis {
                    any_visible |= rule_point;
                    visible_weight += ql.weight * alpha[l];
                } else {
                    any_blocked |= rule_point;
                }
                if kxy > 0.0 {
                    front_points += 1;
                    fq += kxy;
                    front_weight += ql.weight * alpha[l];
                    if vis {
                        front_visible += ql.weight * alpha[l];
                        for ch in 0..3 {
                            e[ch] += kxy * radiosity[l][ch];
                        }
                    }
                }
            }
            if front_weight > 0.0 && rule_point {
                // Mixed verdicts at this point, among the source points it exchanges light with:
                // its share of the source is only as good as the source's samples.
                let v = front_visible / front_weight;
                source_side_err = source_side_err.max(unoccluded * 2.0 * v.min(1.0 - v).max(0.0));
            }
            if fq > 0.0 && front_points > 0 {
                if source_partial && rule_point {
                    coverage_err = coverage_err.max((f_exact - fq).abs() * source_variation);
                }
                let scale = f_exact / fq;
                for x in e.iter_mut() {
                    *x *= scale;
                }
            } else {
                // Every source point is on or behind the receiver's plane (touching elements):
                // the exact form factor with the visible fraction of the source's face mean.
                e = [0.0; 3];
                if rule_point {
                    self.touching.fetch_add(1, Ordering::Relaxed);
                }
                if alpha_weight > 0.0 {
                    e = source_mean.map(|c| c * f_exact * visible_weight / alpha_weight);
                }
            }
            e_k[k] = e;
            if let Some(q) = rrule.get(k) {
                for a in 0..nr {
                    for ch in 0..3 {
                        dh[a][ch] += q.weight * psi[k][a] * e[ch];
                    }
                }
            }
        }

        // Oracle: received irradiance at the control points against its projection.
        let weight = oracle_weight;
        let mut err = max_deviation(&psi[..nk], &e_k[..nk], &dh, nr, weight);
        // A shadow boundary crossing the link: the control points cannot see where it runs, so the
        // whole unoccluded transfer is at stake.
        let mut partial = any_visible && any_blocked;
        let threshold = self.threshold;
        if !partial && any_visible && err * rp.area <= threshold {
            // The quadrature points are interior: the irradiance near the element's border (the
            // falloff towards a room's corners) is not sampled. Compare the exact unoccluded
            // irradiance of the source's mean at points near the corners with the projection.
            for (j, &st) in corner_probe_points(rroot.shape).iter().enumerate() {
                // Off the face, the stand-in receives for the point (see `receiving_point`).
                let x = visibility_point(rroot, &rnode.map, st);
                let f = emitter.form_factor(x, rroot.normal);
                let e = source_mean.map(|c| f * c);
                err = err.max(weighted_deviation(e, &dh, &psi[nk + j], nr, weight));
            }
        }
        if !partial && err * rp.area <= threshold && unoccluded_max * rp.area > threshold {
            // The quadrature rays agree, but they sample the interior only, and sparsely: a shadow
            // boundary near an element's border (a wall standing on a slab, an eave over a wall)
            // slips between them, and so does a strip of a large source seen through a gap. Rays
            // between the corners of both elements, then spread over both, catch them.
            partial = self.verdict_rays_disagree(&rnode.map, rroot, &src.map, any_visible);
        }
        // A source the receiver's points do not see (they lie behind its plane, or beside it)
        // while the source's points see the receiver: the link would carry nothing and pass.
        let missed = self.receiver_misses_source(
            exchange_seen_by_receiver,
            &Exchange {
                rroot,
                rp: &rp,
                rmap: &rnode.map,
                rcover: rcover.as_ref(),
                sp: &sp,
                ys: &ys[..srule.len()],
                alpha: &alpha[..srule.len()],
            },
        );
        if let Some(unseen) = missed {
            err = err.max(unseen * source_strength / rp.area);
        }
        // A leaf whose reflectance varies reflects its mean: the light it puts in the wrong place.
        let reflect_err = reflectance_error(rcv, b, dh[0]);
        err = err.max(reflect_err);
        // The error the control points see across the receiver, before the partial-visibility bound.
        let receiver_err = err;
        if partial {
            err = err.max(unoccluded_max);
        }
        // A partly covered source whose alpha-weighted rule misses the face's shape: only
        // splitting the source sharpens it.
        let coverage_limited = coverage_err > err;
        let err = err.max(coverage_err) * rp.area;
        if err > threshold {
            let can_split_r = rnode.depth < MAX_DEPTH && rp.min_edge() * 0.5 >= self.min_edge;
            let can_split_s = src.depth < MAX_DEPTH && sp.min_edge() * 0.5 >= self.min_edge;
            // The larger side is split, as in hierarchical radiosity; but splitting a source
            // whose radiosity has no finer detail (a leaf, or an emitter's constant) only helps
            // where visibility is partial or the source's coverage is what limits the transfer.
            let source_detail = !self.direct
                && src
                    .node
                    .is_some_and(|n| !self.source_hierarchy.nodes[n].is_leaf());
            // Partial visibility: which side's refinement the error calls for. A shadow boundary
            // across the receiver (its control points disagree with its projection more than the
            // source's samples may be wrong at any point) splits the receiver, however large the
            // source; split source links would each carry too little error to refine it.
            // A source the receiver's points missed: only the receiver's refinement finds it.
            let receiver_first = missed.is_some()
                || reflect_err * rp.area > threshold
                || (partial
                    && receiver_err * rp.area > threshold
                    && receiver_err >= source_side_err);
            let split_source = can_split_s
                && (!can_split_r
                    || coverage_limited
                    || (sp.area > rp.area && !receiver_first && (partial || source_detail)));
            if split_source {
                for child in self.source_children(src) {
                    self.transfer(&child, rcv_index, rcv, b, record);
                }
                return;
            }
            if can_split_r {
                let first = first_child(rcv, b, rroot, &self.rules.cover, rbasis);
                for c in 0..4 {
                    self.transfer(src, rcv_index, rcv, first + c, record);
                }
                return;
            }
            self.capped.fetch_add(1, Ordering::Relaxed);
        }
        self.links.fetch_add(1, Ordering::Relaxed);
        gather(rcv, b, &dh[..nr]);
        if self.node_sums {
            record.add(b, &e_k[..nk + check_points.len()], &dh, src.clone());
        }
    }
}

/// `sum_ch weight_ch |e_ch - projection_ch|` at a point where the receiver's basis functions take
/// the values `phi`: the oracle's measure of a projection's error there.
fn weighted_deviation(
    e: Rgb,
    dh: &[Rgb; MAX_FUNCTIONS],
    phi: &[f64; MAX_FUNCTIONS],
    nr: usize,
    weight: Rgb,
) -> f64 {
    (0..3)
        .map(|ch| {
            let proj: f64 = (0..nr).map(|a| dh[a][ch] * phi[a]).sum();
            weight[ch] * (e[ch] - proj).abs()
        })
        .sum()
}

/// The oracle's error over a set of points: the largest [`weighted_deviation`] of the values `e`
/// from the projection `dh`, the receiver's basis taking the values `psi` at those points.
fn max_deviation(
    psi: &[[f64; MAX_FUNCTIONS]],
    e: &[Rgb],
    dh: &[Rgb; MAX_FUNCTIONS],
    nr: usize,
    weight: Rgb,
) -> f64 {
    debug_assert_eq!(psi.len(), e.len(), "one value per point");
    psi.iter()
        .zip(e)
        .map(|(phi, e)| weighted_deviation(*e, dh, phi, nr, weight))
        .fold(0.0, f64::max)
}

/// What the oracle weighs each channel's irradiance error by: rho for radiance, 1 for irradiance.
fn oracle_weight(quantity: Quantity, rho: Rgb) -> Rgb {
    match quantity {
        Quantity::Radiance => rho,
        Quantity::Irradiance => [1.0; 3],
    }
}

/// The reflected radiosity that leaf `b` of a root whose reflectance varies puts in the wrong
/// place when it receives irradiance of mean `mean_h`: its reflectance's mean absolute deviation
/// times `mean_h`, summed over channels (W/m^2). An element across a sharp colour change reflects
/// their mean; this is what its refinement moves back. Zero for inner nodes (their leaves reflect
/// with their own reflectance) and for roots of constant reflectance.
fn reflectance_error(rcv: &Hierarchy, b: usize, mean_h: Rgb) -> f64 {
    if !rcv.nodes[b].is_leaf() {
        return 0.0;
    }
    let dev = node_reflectance::deviation_of(rcv, b);
    (0..3).map(|ch| dev[ch] * mean_h[ch].abs()).sum()
}

/// The first of node `b`'s four children, splitting `b` first if it is a leaf (an extended
/// root's new children get their covers).
fn first_child(
    rcv: &mut Hierarchy,
    b: usize,
    root: &ElementRoot,
    cover_rules: &CoverRules,
    basis: &Basis,
) -> usize {
    if rcv.nodes[b].is_leaf() {
        let first = rcv.split(b, basis, root.shape);
        cover::extend(rcv, root, cover_rules, basis);
        node_reflectance::extend(rcv, root);
        first
    } else {
        rcv.nodes[b].first_child as usize
    }
}

/// Adds an accepted link's coefficients to node `b`'s gathered irradiance.
fn gather(rcv: &mut Hierarchy, b: usize, dh: &[Rgb]) {
    add_to_gathered(rcv, b, dh, 1.0);
    rcv.touched = true;
}

/// Removes a link's coefficients from node `b`'s gathered irradiance: exactly what `gather` added.
fn take_back(rcv: &mut Hierarchy, b: usize, dh: &[Rgb]) {
    add_to_gathered(rcv, b, dh, -1.0);
}

fn add_to_gathered(rcv: &mut Hierarchy, b: usize, dh: &[Rgb], sign: f64) {
    let nr = dh.len();
    for (a, d) in dh.iter().enumerate() {
        for ch in 0..3 {
            rcv.dh[b * nr + a][ch] += sign * d[ch];
        }
    }
}

/// Points near the corners of a reference shape, inset by [`CORNER_INSET`], and its centroid.
fn corner_probe_points(shape: Shape) -> &'static [DVec2] {
    const E: f64 = CORNER_INSET;
    const SQUARE: [DVec2; 5] = [
        DVec2::new(E, E),
        DVec2::new(1.0 - E, E),
        DVec2::new(1.0 - E, 1.0 - E),
        DVec2::new(E, 1.0 - E),
        DVec2::new(0.5, 0.5),
    ];
    const TRIANGLE: [DVec2; 4] = [
        DVec2::new(E, E),
        DVec2::new(1.0 - 2.0 * E, E),
        DVec2::new(E, 1.0 - 2.0 * E),
        DVec2::new(1.0 / 3.0, 1.0 / 3.0),
    ];
    match shape {
        Shape::Parallelogram => &SQUARE,
        Shape::Triangle => &TRIANGLE,
    }
}

/// Rays between points spread over the two elements of a link whose quadrature rays all agree
/// while the unoccluded transfer exceeds the threshold. With the sky panel's 9 points (M2) and
/// the corner probes all blocked by a parapet, a 2.5 cm face behind it took a third of its light
/// (the Kenney building: 3.3 % nrms; 16 rays still miss the strip of sky it sees, 32 find it:
/// 2.7 %; 64 leave a margin, for 2-25 % more rays in the reference scenes).
const SPREAD_RAYS: usize = 64;

/// How far inside an element its corner probe points, and the spread rays' points, sit, in
/// reference coordinates: off the element's border, where rays would graze the surfaces it meets.
const CORNER_INSET: f64 = 0.02;

/// The two sides of one transfer, as `ShotContext::receiver_misses_source` needs them.
struct Exchange<'a> {
    rroot: &'a ElementRoot,
    rp: &'a Patch,
    rmap: &'a ChildMap,
    rcover: Option<&'a NodeCover>,
    sp: &'a Patch,
    /// The source's rule points and their emission weights (covered fractions).
    ys: &'a [DVec3],
    alpha: &'a [f64],
}

/// The receiver's points see less than this fraction of the exchange the source's points see:
/// they missed the source (a small source close to a large receiver, behind most of it). A
/// disagreement by an order of magnitude is a miss, not the two rules' quadrature error, which
/// refinement along every contact line would chase (a factor of 3 does: measured on the Kenney
/// building, 3.5 % -> 4.2 % nrms from the refinement it causes along contacts).
const MISSED_EXCHANGE_RATIO: f64 = 0.1;

impl ShotContext<'_> {
    /// Reciprocity: `A_r F_rs = A_s F_sr`. The receiver's rule points each take the exact form
    /// factor of the source (`seen_by_receiver`, summed with the rule's weights); the source's
    /// rule points each take the exact form factor of the receiver (of the face inside it on an
    /// extended root). When the receiver's estimate is under `MISSED_EXCHANGE_RATIO` of the
    /// source's, the receiver's points missed the source: returns the unseen exchange
    /// (`A_s F_sr - A_r F_rs`, m^2), else `None`. Without it, a slope meeting a wall delivers
    /// nothing to the wall's root if the wall's nine points all lie behind the slope's plane.
    fn receiver_misses_source(&self, seen_by_receiver: f64, x: &Exchange) -> Option<f64> {
        if x.rcover.is_some_and(|c| c.status == ElementStatus::Empty) {
            // An empty receiver has no face inside: it receives only for its stand-ins, which
            // its neighbours on the face check.
            return None;
        }
        let srule = self.rules.of(self.roots[self.source_root].shape);
        let source_normal = self.roots[self.source_root].normal;
        let rings = partial_face_rings(x.rroot, x.rmap, x.rcover);
        let receiver = Emitter::new(x.rroot, x.rp, rings.as_ref());
        let seen_by_source: f64 = srule
            .iter()
            .zip(x.ys.iter().zip(x.alpha))
            .filter(|(_, (_, &a))| a > 0.0)
            .map(|(q, (&y, &a))| q.weight * a * receiver.form_factor(y, source_normal))
            .sum::<f64>()
            * x.sp.area;
        (seen_by_receiver < MISSED_EXCHANGE_RATIO * seen_by_source)
            .then_some(seen_by_source - seen_by_receiver)
    }

    /// Do rays between the receiver element (`rmap` of `rroot`) and the source element (`smap` of
    /// the shooter) disagree with the quadrature rays' verdict (`quadrature_visible`: all
    /// visible, or all blocked)? First between their corner probe points, then between
    /// [`SPREAD_RAYS`] pairs of points spread over both (a 4-d Kronecker sequence).
    fn verdict_rays_disagree(
        &self,
        rmap: &ChildMap,
        rroot: &ElementRoot,
        smap: &ChildMap,
        quadrature_visible: bool,
    ) -> bool {
        let sroot = &self.roots[self.source_root];
        let (n_r, n_s) = (rroot.normal, sroot.normal);
        let ignore = [sroot.face.0, rroot.face.0];
        // Does the ray from receiver point `x` (its stand-in: it receives as one, see `transfer`)
        // to source point `ss` disagree? Only pairs that exchange light count; the source's
        // stand-in (`stand_in`, O(n) in the face's edges off the face) is asked for only then.
        let disagrees = |x: DVec3, ss: DVec2, stand_in: &mut dyn FnMut() -> DVec3| {
            let y = sroot.frame.point(smap.apply(ss));
            (x - y).dot(n_s) > 0.0
                && (y - x).dot(n_r) > 0.0
                && self.visibility.visible(x, stand_in(), ignore) != quadrature_visible
        };
        let source_corners = corner_probe_points(sroot.shape);
        // The corners' stand-ins serve every receiver corner: computed once, when first needed.
        let mut source_vis: [Option<DVec3>; 5] = [None; 5];
        for &rs in corner_probe_points(rroot.shape) {
            let x = visibility_point(rroot, rmap, rs);
            for (j, &ss) in source_corners.iter().enumerate() {
                let mut stand_in =
                    || *source_vis[j].get_or_insert_with(|| visibility_point(sroot, smap, ss));
                if disagrees(x, ss, &mut stand_in) {
                    return true;
                }
            }
        }
        // Then pairs spread over both elements: a large source seen from a small receiver
        // through a gap (a window reveal under a sky, a box's side behind a parapet) is lit
        // through a strip that the rule's points and the corners all miss.
        (0..SPREAD_RAYS).any(|i| {
            let [a, b, c, d] = quadrature::kronecker4(i);
            let rs = quadrature::inset_into(rroot.shape, DVec2::new(a, b), CORNER_INSET);
            let ss = quadrature::inset_into(sroot.shape, DVec2::new(c, d), CORNER_INSET);
            let x = visibility_point(rroot, rmap, rs);
            disagrees(x, ss, &mut || visibility_point(sroot, smap, ss))
        })
    }
}

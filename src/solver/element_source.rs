//! An element of the shooting root as a [`Source`]: [`SourceElement`] (stored or virtual, with the
//! unshot radiosity it shoots), [`ElementShot`] (one shot's shooter: it makes an element's
//! children, computed by push when they are not stored) and [`ElementSource`], an element as one
//! receiver sees it: the quadrature of its radiosity over its rule's points, one shadow ray per
//! point (one in all for a far link, one per receiver point on [`Rays::Centre`]), scaled to the
//! exact form factor (or, beyond the distance where the rule's own sum is within `1e-4` of the
//! head-on value, `kernel::rule_suffices_radii`, to that sum; a far link takes the sum there on a
//! partly covered element too), and the reciprocity check. Where a receiver point's tangent
//! plane cuts a native or wholly covered element behind some of its rule points, the rule is
//! carried onto the part in front (`front_rule.rs`, by `FrontMap`), so the rays sample what the
//! form factor counts (on every path but a far link's one ray). The one-ray path, a far link's
//! and the centre ray's: `far_link.rs`.
//!
//! Invariants: a partly covered element emits its exact mean over the face inside it
//! (`face_mean`); an empty one emits nothing; the shooter is read-only during its shot.

use super::basis::{child_maps, ChildMap, MAX_FUNCTIONS};
use super::cover::{NodeCover, MAX_RULE_POINTS};
use super::element::{
    partial_face_rings, visibility_point, world_rings, Emitter, FaceRings, FormFactorBound, Patch,
};
use super::hierarchy::Hierarchy;
use super::kernel;
use super::near_verdicts::ALL_VISIBLE;
use super::quadrature::{self, QuadPoint};
use super::refine::Shot;
use super::rules::{corner_probe_points, Bases, Rules, CORNER_INSET};
use super::shot_record::SourcePath;
use super::source::{
    KnownPoint, PointIrradiance, Rays, ReceiverNode, Source, SourceSplit, SPREAD_RAYS,
};
use super::visibility::Visibility;
use super::MAX_DEPTH;
use crate::domain::{ElementRoot, ElementStatus};
use crate::scene::Rgb;
use glam::{DVec2, DVec3};
use std::cell::OnceCell;
use std::sync::Arc;

/// An element of the shooter, stored or virtual (computed by push).
#[derive(Clone)]
pub(super) struct SourceElement {
    pub map: ChildMap,
    pub depth: u8,
    /// The shooter's stored node with this map, when there is one.
    pub node: Option<usize>,
    /// Where the element lies under the shooter's root: the splits that lead to it (the key of
    /// its near links' kept verdicts, `near_verdicts.rs`).
    pub path: SourcePath,
    /// The unshot radiosity shot from this element.
    pub coeffs: [Rgb; MAX_FUNCTIONS],
    /// Extended shooter only: how the element covers the face.
    pub cover: Option<NodeCover>,
    /// A partly covered element's face, for its exact form factor.
    pub rings: Option<Arc<FaceRings>>,
    /// The unshot radiosity's mean over the face inside the element (coefficient 0 unless the
    /// element is partly covered): what the element emits, per unit of face area.
    pub face_mean: Rgb,
}

impl SourceElement {
    /// `face_mean` of an element whose radiosity is its own `coeffs` (a leaf, or virtual: pushed
    /// from one), from its face moments; `stored`: the stored node's mean over its leaves
    /// (`cover::face_means`).
    pub fn face_mean(coeffs: &[Rgb], cover: Option<&NodeCover>, stored: Option<Rgb>) -> Rgb {
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

    /// The shooter's root element, shooting `coeffs` (its emission on a direct shot, else its
    /// unshot radiosity), with `face_mean_stored` its stored face mean when it has one.
    pub fn root(
        root: &ElementRoot,
        coeffs: [Rgb; MAX_FUNCTIONS],
        n: usize,
        cover: Option<NodeCover>,
        face_mean_stored: Option<Rgb>,
    ) -> Self {
        SourceElement {
            face_mean: Self::face_mean(&coeffs[..n], cover.as_ref(), face_mean_stored),
            map: ChildMap::IDENTITY,
            depth: 0,
            node: Some(0),
            path: SourcePath::ROOT,
            coeffs,
            rings: partial_face_rings(root, &ChildMap::IDENTITY, cover.as_ref()),
            cover,
        }
    }
}

/// One shot of a root's unshot radiosity (or, on a direct shot, its emission).
pub(super) struct ElementShot<'a> {
    pub roots: &'a [ElementRoot],
    pub bases: &'a Bases,
    pub rules: &'a Rules,
    pub visibility: &'a Visibility,
    pub source_root: usize,
    pub source_hierarchy: &'a Hierarchy,
    /// A direct shot: the emission alone (a constant), not the shooter's stored unshot.
    pub direct: bool,
    /// An extended shooter's unshot radiosity, per stored node its mean over the face inside
    /// (`cover::face_means`); `None` for a native shooter or a direct shot.
    pub source_face_means: Option<&'a [Rgb]>,
    pub min_edge: f64,
}

impl Shot for ElementShot<'_> {
    type Part = SourceElement;
    type Source<'s>
        = ElementSource<'s>
    where
        Self: 's;

    fn source<'s>(&'s self, src: &'s SourceElement, weight: Rgb) -> Option<ElementSource<'s>> {
        let sroot = &self.roots[self.source_root];
        let ns = self.bases.of(sroot.shape).len();
        if src.coeffs[..ns].iter().all(|c| c.iter().all(|&x| x == 0.0)) {
            return None;
        }
        // Empty elements of an extended domain never emit.
        if src.cover.is_some_and(|c| !c.emits()) {
            return None;
        }
        Some(ElementSource::new(self, src, weight))
    }

    fn verdict_key(&self, s: &SourceElement) -> Option<(usize, SourcePath)> {
        (!self.direct).then_some((self.source_root, s.path))
    }

    fn children(&self, s: &SourceElement) -> [SourceElement; 4] {
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
            SourceElement {
                rings,
                face_mean: SourceElement::face_mean(&coeffs[..n], cover.as_ref(), stored_mean),
                map,
                depth: s.depth + 1,
                node: stored,
                path: s.path.child(c),
                coeffs,
                cover,
            }
        })
    }
}

/// The receiver's points see less than this fraction of the exchange the source's points see:
/// they missed the source (a small source close to a large receiver, behind most of it). A
/// disagreement by an order of magnitude is a miss, not the two rules' quadrature error, which
/// refinement along every contact line would chase (a factor of 3 does: measured on the Kenney
/// building, 3.5 % -> 4.2 % nrms from the refinement it causes along contacts).
const MISSED_EXCHANGE_RATIO: f64 = 0.1;

/// Most rule points (the arrays below are sized for any rule: M3's 4 x 4). Every source a
/// receiver node sees fills arrays of this length: no more than needed.
const POINTS: usize = MAX_RULE_POINTS;

/// A source element as one receiver node sees it: its rule's points, their emission weights and
/// radiosity, and its strength weighted as the oracle's errors are.
pub(super) struct ElementSource<'s> {
    shot: &'s ElementShot<'s>,
    src: &'s SourceElement,
    root: &'s ElementRoot,
    rule: &'s [QuadPoint],
    patch: Patch,
    emitter: Emitter,
    /// The rule's points, and the points their rays go to (stand-ins off an extended face).
    ys: [DVec3; POINTS],
    ys_vis: [DVec3; POINTS],
    /// Emission weights: the rule's, times the covered fraction of each point's zone.
    alpha: [f64; POINTS],
    alpha_weight: f64,
    /// The radiosity at the rule's points (shifted to the face's mean when partly covered).
    radiosity: [Rgb; POINTS],
    partial: bool,
    /// The amplitude of the non-constant part and the mean radiosity, weighted as the oracle's
    /// errors are.
    variation: f64,
    /// The most the non-constant part adds at any point (each function's coefficient times its
    /// [`Basis::max_abs`](super::basis::Basis::max_abs)), weighted likewise.
    amplitude_bound: f64,
    strength: f64,
    /// Where a far link's one shadow ray ends (and each of a [`Rays::Centre`] link's), computed
    /// when first needed ([`ElementSource::far_irradiance_at`]).
    centre_stand_in: OnceCell<DVec3>,
    /// The corners' stand-ins, computed when a ray first needs them.
    corner_stand_ins: [OnceCell<DVec3>; 5],
}

impl<'s> ElementSource<'s> {
    fn new(shot: &'s ElementShot<'s>, src: &'s SourceElement, weight: Rgb) -> Self {
        let root = &shot.roots[shot.source_root];
        let basis = shot.bases.of(root.shape);
        let ns = basis.len();
        let rule = shot.rules.of(root.shape);
        let patch = Patch::new(root, &src.map);
        let emitter = Emitter::new(root, &patch, src.rings.as_ref());
        let mut phi_s = [[0.0; MAX_FUNCTIONS]; POINTS];
        let mut ys = [DVec3::ZERO; POINTS];
        let mut ys_vis = [DVec3::ZERO; POINTS];
        let mut alpha = [1.0f64; POINTS];
        let mut alpha_weight = 0.0;
        for (l, q) in rule.iter().enumerate() {
            basis.eval(q.st, &mut phi_s[l]);
            ys[l] = patch.point(q.st);
            ys_vis[l] = ys[l];
            if let Some(c) = &src.cover {
                alpha[l] = c.alpha[l];
                ys_vis[l] = root.frame.point(c.visibility_point[l]);
            }
            alpha_weight += alpha[l] * q.weight;
        }
        // The source's radiosity at its rule points. A partly covered source's values are shifted
        // by a constant so that their alpha-weighted mean is its exact mean over the face
        // (`SourceElement::face_mean`): the points keep the variation, the constant carries the
        // face's exact power with the exact form factor (near links; a far link's whole transfer
        // is within the threshold, and it takes the rule's sum beyond its radii). The alpha
        // weights alone miss the face's shape (a sliver of face along the element's border takes
        // the weight of points well inside, where the polynomial differs), and an inner node's
        // polynomial is its projection over the whole element, off-face extension included:
        // unshifted, a Red Eclipse floor's shot delivered 1.6x its unshot power.
        let source_mean = src.face_mean;
        let mut radiosity = [[0.0f64; 3]; POINTS];
        for (l, b) in radiosity.iter_mut().take(rule.len()).enumerate() {
            for bfn in 0..ns {
                for ch in 0..3 {
                    b[ch] += phi_s[l][bfn] * src.coeffs[bfn][ch];
                }
            }
        }
        let partial = src
            .cover
            .is_some_and(|c| c.status == ElementStatus::Partial);
        if partial && alpha_weight > 0.0 {
            let mut rule_mean = [0.0; 3];
            for (l, q) in rule.iter().enumerate() {
                for ch in 0..3 {
                    rule_mean[ch] += q.weight * alpha[l] * radiosity[l][ch] / alpha_weight;
                }
            }
            for b in radiosity.iter_mut().take(rule.len()) {
                for ch in 0..3 {
                    b[ch] += source_mean[ch] - rule_mean[ch];
                }
            }
        }
        // The amplitude of the source's non-constant part: what a misplaced emission weight can
        // move (the constant part is exact where the exact form factor is used).
        let weighted_amplitude = |bfn: usize| {
            (0..3)
                .map(|ch| weight[ch] * src.coeffs[bfn][ch].abs())
                .sum::<f64>()
        };
        let variation: f64 = (1..ns).map(weighted_amplitude).sum();
        // What the non-constant part adds at most at any point of the element.
        let amplitude_bound: f64 = (1..ns)
            .map(|bfn| weighted_amplitude(bfn) * basis.max_abs(bfn))
            .sum();
        // The source's mean radiosity, weighted as the oracle's errors are.
        let strength: f64 = (0..3).map(|ch| weight[ch] * source_mean[ch].abs()).sum();
        ElementSource {
            shot,
            src,
            root,
            rule,
            patch,
            emitter,
            ys,
            ys_vis,
            alpha,
            alpha_weight,
            radiosity,
            partial,
            variation,
            amplitude_bound,
            strength,
            centre_stand_in: OnceCell::new(),
            corner_stand_ins: Default::default(),
        }
    }

    /// A bound on the power the element may send (channels summed and weighted as the oracle's
    /// errors): at any point its radiosity's magnitude is at most its mean's plus
    /// `amplitude_bound`. On a partly covered element each point's value is the polynomial's there
    /// minus the rule's mean plus the face's mean (`new`); the first two are each within
    /// `amplitude_bound` of coefficient 0, so the value is within twice it of the face's mean,
    /// whatever that mean is (a stored mean over the leaves too). Times the face's area inside the
    /// element, which is at most the element's and the face's. Pinned on native elements by
    /// `power_bound_holds_over_the_face` (`far_field.rs`).
    pub(super) fn power_bound(&self) -> f64 {
        let margin = if self.partial { 2.0 } else { 1.0 };
        (self.strength + margin * self.amplitude_bound)
            * self.patch.area.min(self.root.face_area_m2)
    }

    /// Do receiver point `x` (normal `n`) and the source's point `y` exchange light?
    fn exchange(&self, x: DVec3, n: DVec3, y: DVec3) -> bool {
        (x - y).dot(self.root.normal) > 0.0 && (y - x).dot(n) > 0.0
    }

    /// The unoccluded form factor at `x` (normal `n`): the sum of the source's rule where it is
    /// within its bound of the exact value (`Emitter::rule_suffices`: far enough, the source
    /// wholly in front of `x`), else the exact contour integral. The rule's sum is what
    /// [`ElementSource::with_verdicts`] sums, term by term, so the rescaling there is exactly 1.
    fn form_factor(&self, x: DVec3, n: DVec3) -> f64 {
        self.form_factor_and_terms(x, n).0
    }

    /// [`ElementSource::form_factor`], and where it is the rule's sum, the rule's terms it summed
    /// ([`ElementSource::point_terms`]), for [`ElementSource::with_verdicts`] to sum again
    /// without computing them twice.
    fn form_factor_and_terms(&self, x: DVec3, n: DVec3) -> (f64, Option<[f64; POINTS]>) {
        if self
            .emitter
            .rule_suffices(x, n, self.shot.rules.form_factor_radii)
        {
            let terms = self.point_terms(x, n);
            (self.sum_of_front(&terms), Some(terms))
        } else {
            (self.emitter.form_factor(x, n), None)
        }
    }

    /// The rule's form factor from its points' terms ([`ElementSource::point_terms`]): the
    /// positive ones (the emitting points in front) summed in the rule's order, the sum
    /// [`ElementSource::with_verdicts`] rescales by.
    fn sum_of_front(&self, terms: &[f64; POINTS]) -> f64 {
        terms[..self.rule.len()]
            .iter()
            .filter(|&&kxy| kxy > 0.0)
            .fold(0.0, |sum, &kxy| sum + kxy)
    }

    /// Each rule point's [`ElementSource::point_term`] at `x` (normal `n`); 0 where the point
    /// does not emit (`alpha` 0), as the sums over emitting points skip it.
    fn point_terms(&self, x: DVec3, n: DVec3) -> [f64; POINTS] {
        let mut terms = [0.0; POINTS];
        for (l, ql) in self.rule.iter().enumerate() {
            if self.alpha[l] > 0.0 {
                terms[l] = self.point_term(l, ql.weight, x, n);
            }
        }
        terms
    }

    /// The source's exchange with something seen from its emitting rule points, `form_factor(y)`
    /// at each (m^2): the rule's weighted sum over the points, times the element's area.
    fn exchange_from_rule(&self, form_factor: impl Fn(DVec3) -> f64) -> f64 {
        let n = self.rule.len();
        self.rule
            .iter()
            .zip(self.ys[..n].iter().zip(&self.alpha[..n]))
            .filter(|(_, (_, &a))| a > 0.0)
            .map(|(q, (&y, &a))| q.weight * a * form_factor(y))
            .sum::<f64>()
            * self.patch.area
    }

    /// Rule point `l`'s term of the form factor at `x` (normal `n`): the kernel times the
    /// element's area, the point's weight `w` and its emission weight. One expression for the
    /// rule's form factor ([`ElementSource::point_terms`]), `rule_sums` and
    /// [`ElementSource::with_verdicts`], so their sums agree bit for bit.
    fn point_term(&self, l: usize, w: f64, x: DVec3, n: DVec3) -> f64 {
        kernel::geometric_kernel(x, n, self.ys[l], self.root.normal)
            * self.patch.area
            * w
            * self.alpha[l]
    }

    /// The emitting rule points lying in front of `x` (normal `n`), in the rule's order: each
    /// index and its positive [`ElementSource::point_term`], the terms
    /// [`ElementSource::with_verdicts`] sums (whatever their rays' verdicts).
    fn front_terms(&self, x: DVec3, n: DVec3) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.rule
            .iter()
            .enumerate()
            .filter(|&(l, _)| self.alpha[l] > 0.0)
            .map(move |(l, ql)| (l, self.point_term(l, ql.weight, x, n)))
            .filter(|&(_, kxy)| kxy > 0.0)
    }

    /// The rule's sum of the kernel from `x` over the emitting points (the positive terms
    /// [`ElementSource::with_verdicts`] sums), wherever `x` is: what
    /// [`ElementSource::form_factor`] takes beyond the rule's radii.
    #[cfg(test)]
    fn rule_form_factor(&self, x: DVec3, n: DVec3) -> f64 {
        self.sum_of_front(&self.point_terms(x, n))
    }

    /// What the source delivers at `x` (normal `n`, unoccluded form factor `f > 0` from
    /// [`ElementSource::form_factor`]) given the verdicts `seen` of its emitting rule points, bit
    /// `i` for the `i`-th of them.
    /// `terms`: the rule's terms at `x` when the caller has them ([`ElementSource::point_terms`]).
    fn with_verdicts(
        &self,
        x: DVec3,
        n: DVec3,
        f: f64,
        mut seen: u64,
        terms: Option<&[f64; POINTS]>,
    ) -> PointIrradiance {
        let mut out = self.unread_answer(f, seen);
        let unoccluded = out.unoccluded;
        let alpha = &self.alpha;
        let mut fq = 0.0;
        let mut e = [0.0; 3];
        let mut visible_weight = 0.0;
        let mut front_points = 0usize;
        let (mut front_weight, mut front_visible) = (0.0, 0.0);
        for (l, ql) in self.rule.iter().enumerate() {
            if alpha[l] <= 0.0 {
                continue;
            }
            let kxy = match terms {
                Some(t) => t[l],
                None => self.point_term(l, ql.weight, x, n),
            };
            let vis = seen & 1 == 1;
            seen >>= 1;
            if vis {
                out.any_visible = true;
                visible_weight += ql.weight * alpha[l];
            } else {
                out.any_blocked = true;
            }
            if kxy > 0.0 {
                front_points += 1;
                fq += kxy;
                front_weight += ql.weight * alpha[l];
                if vis {
                    front_visible += ql.weight * alpha[l];
                    for ch in 0..3 {
                        e[ch] += kxy * self.radiosity[l][ch];
                    }
                }
            }
        }
        if front_weight > 0.0 {
            // Mixed verdicts at this point, among the source points it exchanges light with:
            // its share of the source is only as good as the source's samples.
            let v = front_visible / front_weight;
            out.source_side_err = unoccluded * 2.0 * v.min(1.0 - v).max(0.0);
        }
        if fq > 0.0 && front_points > 0 {
            if self.partial {
                out.coverage_err = (f - fq).abs() * self.variation;
            }
            let scale = f / fq;
            for x in e.iter_mut() {
                *x *= scale;
            }
        } else {
            // Every source point is on or behind the receiver's plane (touching elements):
            // the exact form factor with the visible fraction of the source's face mean.
            e = [0.0; 3];
            out.touching = true;
            if self.alpha_weight > 0.0 {
                e = self
                    .src
                    .face_mean
                    .map(|c| c * f * visible_weight / self.alpha_weight);
            }
        }
        out.e = e;
        out
    }

    /// A point's answer before its verdicts are read into it: the unoccluded irradiance of form
    /// factor `f` and the verdicts `seen` (`with_verdicts` and `front_irradiance` fill the rest).
    fn unread_answer(&self, f: f64, seen: u64) -> PointIrradiance {
        PointIrradiance {
            unoccluded: f * self.strength,
            form_factor: f,
            seen,
            ..PointIrradiance::default()
        }
    }

    /// The packet of shadow rays from `x` to the rule's points that emit, in the rule's order
    /// (`with_verdicts` skips the others with the same test, so it reads the verdicts in packing
    /// order): one bit per ray, [`ALL_VISIBLE`] when all passed.
    fn trace_rule(&self, x: DVec3, ignore: [u32; 2]) -> u64 {
        let mut targets = [DVec3::ZERO; POINTS];
        let mut rays = 0;
        for l in 0..self.rule.len() {
            if self.alpha[l] <= 0.0 {
                continue;
            }
            targets[rays] = self.ys_vis[l];
            rays += 1;
        }
        trace_packet(self.shot.visibility, x, &targets[..rays], ignore)
    }
}

impl Source for ElementSource<'_> {
    fn ignored_faces(&self, receiver_face: u32) -> [u32; 2] {
        [self.root.face.0, receiver_face]
    }

    fn irradiance_at(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: [u32; 2],
        rays: Rays,
        known: Option<KnownPoint>,
    ) -> Option<PointIrradiance> {
        let (f, terms) = match known {
            Some(k) => (k.form_factor, None),
            None => self.form_factor_and_terms(x, n),
        };
        if f <= 0.0 {
            return None;
        }
        let seen = known.map(|k| k.seen);
        if let Some(front) = self.front_rule(x, n) {
            if let Some(out) = self.front_irradiance((x, n, f), ignore, &front, (rays, seen)) {
                return Some(out);
            }
        }
        let seen = verdicts(
            (rays, seen),
            || self.trace_rule(x, ignore),
            || self.centre_verdict(x, ignore),
        );
        Some(self.with_verdicts(x, n, f, seen, terms.as_ref()))
    }

    fn unoccluded_irradiance(&self, x: DVec3, n: DVec3) -> Rgb {
        let f = self.form_factor(x, n);
        self.src.face_mean.map(|c| f * c)
    }

    fn corner_rays(&self, x: DVec3, n: DVec3, disagrees: &mut dyn FnMut(DVec3) -> bool) -> bool {
        // Only pairs that exchange light count; the source's stand-in (O(n) in the face's edges
        // off the face) is asked for only then, once per corner for every receiver point.
        let (root, map) = (self.root, &self.src.map);
        corner_probe_points(root.shape)
            .iter()
            .enumerate()
            .any(|(j, &ss)| {
                self.exchange(x, n, root.frame.point(map.apply(ss)))
                    && disagrees(
                        *self.corner_stand_ins[j].get_or_init(|| visibility_point(root, map, ss)),
                    )
            })
    }

    fn spread_rays(&self) -> usize {
        SPREAD_RAYS
    }

    fn spread_ray(
        &self,
        x: DVec3,
        n: DVec3,
        st: DVec2,
        disagrees: &mut dyn FnMut(DVec3) -> bool,
    ) -> bool {
        let (root, map) = (self.root, &self.src.map);
        let ss = quadrature::inset_into(root.shape, st, CORNER_INSET);
        self.exchange(x, n, root.frame.point(map.apply(ss)))
            && disagrees(visibility_point(root, map, ss))
    }

    /// Reciprocity: `A_r F_rs = A_s F_sr`. The receiver's rule points each take the form factor
    /// of the source (`ElementSource::form_factor`; `seen_by_receiver`, summed with the rule's
    /// weights); the source's rule points each take the exact form factor of the receiver (of
    /// the face inside it on an extended root). When the receiver's estimate is under
    /// `MISSED_EXCHANGE_RATIO` of the source's, the receiver's points missed the source: the
    /// unseen exchange (`A_s F_sr - A_r F_rs`, m^2) times the source's strength, over the
    /// receiver's area. Without it, a slope meeting a wall delivers nothing to the wall's root if
    /// the wall's nine points all lie behind the slope's plane.
    fn missed_by(&self, r: &ReceiverNode, seen_by_receiver: f64) -> Option<f64> {
        if r.cover.is_some_and(|c| c.status == ElementStatus::Empty) {
            // An empty receiver has no face inside: it receives only for its stand-ins, which
            // its neighbours on the face check.
            return None;
        }
        // The exact exchange is asked only when a bound on it could reach ten times the
        // receiver's (a sky piece far above a small receiver is decided here).
        let bound = FormFactorBound::new(r.root, &r.patch);
        let source_bound = self.exchange_from_rule(|y| bound.at(y, self.root.normal));
        // (The margin is for rounding: the bound is a true upper bound of the exact value, which
        // the contour integrals give to about 1e-12; `FormFactorBound`'s test allows 1e-9.)
        if seen_by_receiver >= MISSED_EXCHANGE_RATIO * source_bound * (1.0 + 1e-6) {
            return None;
        }
        let rings = partial_face_rings(r.root, &r.map, r.cover);
        let receiver = Emitter::new(r.root, &r.patch, rings.as_ref());
        let seen_by_source = self.exchange_from_rule(|y| receiver.form_factor(y, self.root.normal));
        (seen_by_receiver < MISSED_EXCHANGE_RATIO * seen_by_source)
            .then(|| (seen_by_source - seen_by_receiver) * self.strength / r.patch.area)
    }

    fn split(&self) -> SourceSplit {
        let h = self.shot.source_hierarchy;
        SourceSplit {
            can_split: self.src.depth < MAX_DEPTH
                && self.patch.min_edge() * 0.5 >= self.shot.min_edge,
            area: self.patch.area,
            // Splitting a source whose radiosity has no finer detail (a leaf, or an emitter's
            // constant) only helps where visibility is partial or its coverage limits the
            // transfer.
            detail: !self.shot.direct && self.src.node.is_some_and(|n| !h.nodes[n].is_leaf()),
        }
    }
}

/// A receiver point's verdicts (one bit per sample point of the rule in use: the element's
/// emitting points, or the front rule's) as `rays` decides them: every point seen on
/// [`Rays::AllPass`], even where an earlier shot's verdicts are `known`; else the known ones;
/// else one ray per point (`trace`) or one ray for all of them (`centre`).
/// `transfer::tests::rays_taken_as_passing_trace_none_and_see_the_source_whole` pins the first,
/// `transfer::tests::centre_rays_trace_one_ray_per_point_and_give_all_or_nothing` the last.
fn verdicts(
    (rays, known): (Rays, Option<u64>),
    trace: impl FnOnce() -> u64,
    centre: impl FnOnce() -> u64,
) -> u64 {
    match (rays, known) {
        (Rays::AllPass, _) => ALL_VISIBLE,
        (_, Some(seen)) => seen,
        (Rays::Trace, None) => trace(),
        (Rays::Centre, None) => centre(),
    }
}

/// The packet of shadow rays from `x` to `targets`, counted: one bit per ray, [`ALL_VISIBLE`]
/// when all passed (so a point's verdict reads the same whatever its number of rays).
fn trace_packet(visibility: &Visibility, x: DVec3, targets: &[DVec3], ignore: [u32; 2]) -> u64 {
    visibility.count_rays(targets.len() as u64);
    let seen = visibility.visible_from(x, targets, ignore);
    let all = u64::MAX >> (64 - targets.len().clamp(1, 64));
    if !targets.is_empty() && seen & all == all {
        ALL_VISIBLE
    } else {
        seen
    }
}

mod far_link;
mod front_rule;

#[cfg(test)]
pub(super) mod tests;

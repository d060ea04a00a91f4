//! What a transfer asks of whatever shoots: the [`Source`] interface, shared by elements of the
//! shooter (`element_source.rs`) and punctual lights ([`LightSource`]), after pbrt-v4's `Light`
//! as `SampleLd` uses it. A source answers "irradiance at x" (occlusion included), "unoccluded
//! irradiance at x", and "where do the shadow rays from x go" (corner and spread rays, to check
//! the quadrature's verdict), and beside those which faces its rays ignore, what the receiver's
//! points missed of it (reciprocity) and how it splits; the transfer (`transfer.rs`) and the
//! oracle (`oracle.rs`) know nothing else of it.
//!
//! Also owns [`ReceiverNode`], the receiving side of one interaction, and where the spread rays
//! that check a verdict start and end ([`SPREAD_RAYS`], [`spread_st`]).
//!
//! Invariant: a source's point answers and its shadow rays cast exactly the rays its transfer
//! needs, in a fixed order (the ray count is part of the solve's statistics).

use super::basis::ChildMap;
use super::cover::{self, NodeCover, MAX_POINTS};
use super::element::visibility_point;
use super::element::Patch;
use super::hierarchy::{Hierarchy, SpreadPoints};
use super::lights::{shadow_target, unoccluded_irradiance};
use super::mean_rgb_sum;
use super::near_verdicts::ALL_VISIBLE;
use super::node_reflectance;
use super::quadrature;
use super::refine::Shot;
use super::rules::{corner_probe_points, Rules, CORNER_INSET};
use super::shot_record::SourcePath;
use super::visibility::Visibility;
use crate::domain::{ElementRoot, Shape};
use crate::scene::{PunctualLight, Rgb};
use glam::{DVec2, DVec3};

/// How a transfer decides its shadow rays' verdicts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Rays {
    /// Trace them.
    Trace,
    /// Take every one as passing, tracing none: a link the node-sum check re-sends to a child of
    /// its node where all its rays from the node's points inside the child passed
    /// (`node_sums.rs`), on a fully covered or native child, and the source's parts if the
    /// oracle splits the source there (not the child's children: they trace). No ray checks the
    /// oracle's verdict either.
    AllPass,
    /// One ray per receiver point, to the source's centre, its verdict standing for every sample
    /// of the source (as a far link's one ray does): an indirect shot's link to a receiver apart
    /// from the shooter that would get a small share of the threshold with no occluder
    /// (`pass::centre_rays_suffice`), and the links the oracle refines it into (the node-sum
    /// check re-sends its links tracing). No ray checks the oracle's verdict
    /// (`transfer::tests::centre_rays_trace_one_ray_per_point_and_give_all_or_nothing`).
    Centre,
}

/// What a receiver point saw of an element source when a shot of the same root evaluated it
/// before (`near_verdicts.rs`): its rays' verdicts ([`PointIrradiance::seen`]) and the source's
/// form factor ([`PointIrradiance::form_factor`]; 0 where nothing reached it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct KnownPoint {
    pub seen: u64,
    pub form_factor: f64,
}

/// What a source delivers at one receiver point.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct PointIrradiance {
    /// Irradiance received at the point, occlusion included.
    pub e: Rgb,
    /// Unoccluded irradiance at the point, channels weighted as the oracle's errors.
    pub unoccluded: f64,
    /// The source's unoccluded form factor from the point (element sources: exact, or the rule's
    /// sum where that is within its bound, `ElementSource::form_factor`; the reciprocity check
    /// sums it), 0 for lights.
    pub form_factor: f64,
    /// Whether any of the point's rays to the source was unblocked, and any blocked.
    pub any_visible: bool,
    pub any_blocked: bool,
    /// Partial visibility among the source's samples: the error they may cause at this point.
    pub source_side_err: f64,
    /// A partly covered source: how far its alpha-weighted rule is from the exact form factor,
    /// times its non-constant part (only splitting the source sharpens it).
    pub coverage_err: f64,
    /// No source point lay in front of the receiver (touching elements): the exact form factor
    /// times the visible fraction stood in for the quadrature.
    pub touching: bool,
    /// What the point's shadow rays said, one bit per ray in the order they were cast
    /// ([`ALL_VISIBLE`] when all passed): a verdict a later shot may read back as `known`.
    pub seen: u64,
}

/// Whether, and how, the oracle may split a source.
#[derive(Debug, Clone, Copy)]
pub(super) struct SourceSplit {
    /// Not at the depth or size limit (never for a punctual light).
    pub can_split: bool,
    /// The source element's area (m^2).
    pub area: f64,
    /// Its radiosity has finer detail than its own coefficients (a stored inner node).
    pub detail: bool,
}

/// A source of light as one receiver node sees it.
pub(super) trait Source {
    /// The faces the shadow rays to the source ignore, given the receiver's face: the receiver's,
    /// and the source element's own.
    fn ignored_faces(&self, receiver_face: u32) -> [u32; 2];

    /// What the source delivers at receiver point `x` (normal `n`), its shadow rays ignoring the
    /// faces `ignore` ([`Source::ignored_faces`]); `None` when nothing reaches it unoccluded
    /// (behind the source, outside a spot's cone).
    /// `rays`: trace the shadow rays, take them all as passing, or cast one per point to the
    /// source's centre ([`Rays`]); `known`: what they said and the form factor when a shot
    /// evaluated the point before (`near_verdicts.rs`), read instead of traced and computed.
    fn irradiance_at(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: [u32; 2],
        rays: Rays,
        known: Option<KnownPoint>,
    ) -> Option<PointIrradiance>;

    /// The unoccluded irradiance at `x` of the source's mean (the oracle's corner probes).
    fn unoccluded_irradiance(&self, x: DVec3, n: DVec3) -> Rgb;

    /// Shadow rays from receiver point `x` (normal `n`) towards the source's corners, those that
    /// exchange light: true as soon as `disagrees(target)` does for one of them.
    fn corner_rays(&self, x: DVec3, n: DVec3, disagrees: &mut dyn FnMut(DVec3) -> bool) -> bool;

    /// How many spread rays check the verdict beyond the corners (0: none).
    fn spread_rays(&self) -> usize;

    /// The spread ray from receiver point `x` to the source's point `st` (reference coordinates,
    /// inset from its border), if they exchange light: `disagrees(target)`, else false.
    fn spread_ray(
        &self,
        x: DVec3,
        n: DVec3,
        st: DVec2,
        disagrees: &mut dyn FnMut(DVec3) -> bool,
    ) -> bool;

    /// Reciprocity: when the receiver's points missed the source (`seen_by_receiver`, the
    /// exchange they saw, m^2, is far below what the source's points see), the irradiance error
    /// the unseen exchange stands for; `None` otherwise, and always for lights.
    fn missed_by(&self, receiver: &ReceiverNode, seen_by_receiver: f64) -> Option<f64>;

    /// Whether the oracle may split this source.
    fn split(&self) -> SourceSplit;
}

/// Rays between points spread over the two elements of a link whose quadrature rays all agree
/// while the unoccluded transfer exceeds the threshold. With the sky panel's 9 points (M2) and
/// the corner probes all blocked by a parapet, a 2.5 cm face behind it took a third of its light
/// (the Kenney building: 3.3 % nrms; 16 rays still miss the strip of sky it sees, 32 find it:
/// 2.7 %; 64 leave a margin, for 2-25 % more rays in the reference scenes).
pub(super) const SPREAD_RAYS: usize = 64;

/// Spread point `i` of an element in its reference coordinates: the first two coordinates of
/// [`quadrature::kronecker4`]`(i)`, inset as the corner probes are (the last two spread over the
/// source).
pub(super) fn spread_st(shape: Shape, i: usize) -> DVec2 {
    let [a, b, _, _] = quadrature::kronecker4(i);
    quadrature::inset_into(shape, DVec2::new(a, b), CORNER_INSET)
}

/// The receiving side of one interaction: node `index` of a root's hierarchy.
pub(super) struct ReceiverNode<'a> {
    pub root: &'a ElementRoot,
    pub map: ChildMap,
    pub depth: u8,
    pub patch: Patch,
    /// Extended roots: how the node covers the face.
    pub cover: Option<&'a NodeCover>,
    /// For each point (rule points, then check points), the first point asked before whose
    /// answer it takes, itself if none: an extended root's node's own stand-ins
    /// ([`NodeCover::alike`]), a native root's the shape's ([`Rules::alike`]).
    pub alike: &'a [u8; MAX_POINTS],
    /// A leaf whose reflectance varies: its deviation from its mean (see `reflectance_error`).
    pub reflectance_deviation: Option<Rgb>,
    /// Extended roots: the node's spread points on the face, kept with the hierarchy.
    pub spread_points: Option<&'a SpreadPoints>,
}

impl<'a> ReceiverNode<'a> {
    /// Node `index` of `h`, a hierarchy of `root`; `rules` give a native root's `alike` map
    /// ([`Rules::alike`]).
    pub fn new(root: &'a ElementRoot, h: &'a Hierarchy, index: usize, rules: &'a Rules) -> Self {
        let node = h.nodes[index];
        let cover = cover::of_node(h, root, index);
        ReceiverNode {
            root,
            map: node.map,
            depth: node.depth,
            patch: Patch::new(root, &node.map),
            cover,
            alike: cover.map_or(rules.alike(root.shape), |c| &c.alike),
            reflectance_deviation: node
                .is_leaf()
                .then(|| node_reflectance::deviation_of(h, index)),
            spread_points: h.spread_points.get(index),
        }
    }

    /// Where the node's spread point `i` ([`spread_st`]) casts its rays: the point itself, or
    /// off an extended face its stand-in (`visibility_point`). An extended root's node computes
    /// its first [`SPREAD_RAYS`] stand-ins once, when a link first asks, and keeps them with the
    /// hierarchy (a closest point is O(n) in the face's edges, and every link of the node whose
    /// rays agree asks them all); the same points as `visibility_point`'s, bit for bit
    /// (`spread_points_are_the_visibility_points`).
    pub fn spread_point(&self, i: usize) -> DVec3 {
        let shape = self.root.shape;
        match (self.spread_points, &self.root.mask) {
            (Some(kept), Some(mask)) if i < SPREAD_RAYS => {
                let points = kept.get_or_init(|| {
                    (0..SPREAD_RAYS)
                        .map(|k| mask.closest_point(self.map.apply(spread_st(shape, k))))
                        .collect()
                });
                self.root.frame.point(points[i])
            }
            _ => visibility_point(self.root, &self.map, spread_st(shape, i)),
        }
    }

    /// Where the node's check point `j` (`rules::corner_probe_points`) casts its rays and
    /// receives: the point itself, or off an extended face its stand-in, the closest point on
    /// the face (`visibility_point`), as the node's cover holds it.
    pub fn check_point(&self, j: usize) -> DVec3 {
        // Extended roots are parallelograms: their covers hold a parallelogram's check points.
        debug_assert!(self.cover.is_none() || self.root.shape == Shape::Parallelogram);
        match self.cover {
            Some(c) => self.root.frame.point(c.check_point[j]),
            None => visibility_point(
                self.root,
                &self.map,
                corner_probe_points(self.root.shape)[j],
            ),
        }
    }
}

/// A punctual light as a source: its irradiance at a point and one shadow ray to it.
pub(super) struct LightSource<'a> {
    pub light: &'a PunctualLight,
    /// A distance beyond the scene: where a directional light's shadow rays end.
    pub far: f64,
    pub visibility: &'a Visibility,
    /// The oracle's channel weights at the receiver.
    pub weight: Rgb,
}

impl Source for LightSource<'_> {
    fn ignored_faces(&self, receiver_face: u32) -> [u32; 2] {
        [receiver_face; 2]
    }

    fn irradiance_at(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: [u32; 2],
        rays: Rays,
        known: Option<KnownPoint>,
    ) -> Option<PointIrradiance> {
        let (e, target) = unoccluded_irradiance(self.light, x, n, self.far);
        if mean_rgb_sum(e) <= 0.0 {
            return None;
        }
        let weight = self.weight;
        let unoccluded = (0..3).map(|c| weight[c] * e[c]).sum::<f64>();
        let visible = rays == Rays::AllPass
            || known.map_or_else(
                || self.visibility.visible(x, target, ignore),
                |k| k.seen & 1 == 1,
            );
        Some(PointIrradiance {
            e: if visible { e } else { [0.0; 3] },
            unoccluded,
            any_visible: visible,
            any_blocked: !visible,
            seen: if visible { ALL_VISIBLE } else { 0 },
            ..PointIrradiance::default()
        })
    }

    fn unoccluded_irradiance(&self, x: DVec3, n: DVec3) -> Rgb {
        unoccluded_irradiance(self.light, x, n, self.far).0
    }

    fn corner_rays(&self, x: DVec3, n: DVec3, disagrees: &mut dyn FnMut(DVec3) -> bool) -> bool {
        let (e, _) = unoccluded_irradiance(self.light, x, n, self.far);
        if mean_rgb_sum(e) <= 0.0 {
            return false;
        }
        disagrees(shadow_target(self.light, x, self.far))
    }

    fn spread_rays(&self) -> usize {
        0
    }

    fn spread_ray(&self, _: DVec3, _: DVec3, _: DVec2, _: &mut dyn FnMut(DVec3) -> bool) -> bool {
        false
    }

    fn missed_by(&self, _: &ReceiverNode, _: f64) -> Option<f64> {
        None
    }

    fn split(&self) -> SourceSplit {
        SourceSplit {
            can_split: false,
            area: 0.0,
            detail: false,
        }
    }
}

/// One punctual light's shot: a single part (the light is never split).
pub(super) struct LightShot<'a> {
    pub light: &'a PunctualLight,
    pub far: f64,
    pub visibility: &'a Visibility,
}

impl Shot for LightShot<'_> {
    type Part = ();
    type Source<'s>
        = LightSource<'s>
    where
        Self: 's;

    fn source<'s>(&'s self, _: &'s (), weight: Rgb) -> Option<LightSource<'s>> {
        Some(LightSource {
            light: self.light,
            far: self.far,
            visibility: self.visibility,
            weight,
        })
    }

    fn verdict_key(&self, _: &()) -> Option<(usize, SourcePath)> {
        None
    }

    fn children(&self, _: &()) -> [(); 4] {
        unreachable!("a punctual light is never split: its `SourceSplit::can_split` is false")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::basis::Basis;
    use crate::solver::element::tests::parallelogram_root;

    /// The spread points an extended root's node keeps are `visibility_point`'s, bit for bit, at
    /// every node of a split hierarchy (points in the face's hole stand in on its border), and
    /// beyond the ones kept; a native root keeps none and gives the same points.
    #[test]
    fn spread_points_are_the_visibility_points() {
        let order = 2;
        let rules = Rules::new(order);
        let basis = Basis::new(Shape::Parallelogram, order);
        let mut root = parallelogram_root(DVec3::ZERO, DVec3::X, DVec3::Y);
        let native = root.clone();
        root.mask = Some(crate::solver::cover::tests::holed(0.5));
        root.face_area_m2 = 0.75;
        for root in [root, native] {
            let mut h = Hierarchy::of_root(&root, &basis, &rules.cover);
            let first = h.split_element(0, &root, &basis, &rules.cover);
            h.split_element(first + 2, &root, &basis, &rules.cover);
            let extended = root.mask.is_some();
            assert_eq!(
                h.spread_points.len(),
                if extended { h.nodes.len() } else { 0 }
            );
            let mut moved = 0;
            for index in 0..h.nodes.len() {
                let node = ReceiverNode::new(&root, &h, index, &rules);
                for i in 0..SPREAD_RAYS + 3 {
                    let st = spread_st(root.shape, i);
                    let expected = visibility_point(&root, &node.map, st);
                    assert_eq!(node.spread_point(i), expected, "node {index}, point {i}");
                    moved += usize::from(expected != root.frame.point(node.map.apply(st)));
                }
                assert_eq!(
                    h.spread_points
                        .get(index)
                        .is_some_and(|p| p.get().is_some()),
                    extended
                );
            }
            assert_eq!(moved > 0, extended, "{moved} points stand in off the face");
            // Emptied when the solve ends: the bytes are the nodes' again.
            let asked = h.bytes();
            h.forget_solve_caches();
            assert!(h.spread_points.iter().all(|p| p.get().is_none()));
            let kept = h.nodes.len() * SPREAD_RAYS * std::mem::size_of::<DVec2>();
            assert_eq!(asked - h.bytes(), if extended { kept as u64 } else { 0 });
        }
    }
}

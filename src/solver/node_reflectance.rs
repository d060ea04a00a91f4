//! The reflectance of each element of a root whose reflectance varies (a textured face): the mean
//! of the root's [`ReflectanceMap`] over the element's footprint, and how far it strays from that
//! mean (the mean absolute deviation, which the oracle turns into misplaced reflected power).
//!
//! Invariants: a root with a map has one [`NodeReflectance`] per node ([`extend`] runs wherever
//! covers are extended: a new hierarchy, a split, a loaded solution); a root without one has none
//! and uses its constant `rho`. Pinned by `tests/textures.rs` (a ramp's reflected power).

use super::basis::ChildMap;
use super::hierarchy::Hierarchy;
use crate::domain::{ElementRoot, ReflectanceMap, Shape};
use crate::scene::Rgb;
use glam::DVec2;

/// Reflectance of one element: its mean over the element's face and the mean absolute deviation
/// from it, per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeReflectance {
    pub mean: Rgb,
    pub deviation: Rgb,
}

/// Points per side of the grid a triangle element's reflectance is averaged over.
const SAMPLES: usize = 16;

/// The sample points of a triangle element in its own reference coordinates: the centres of a
/// 16 x 16 grid inside it (a parallelogram element, a box of its root's `(s, t)`, is averaged
/// over exactly instead).
fn sample_points(shape: Shape) -> impl Iterator<Item = DVec2> + Clone {
    (0..SAMPLES * SAMPLES).filter_map(move |k| {
        let st = DVec2::new(
            ((k % SAMPLES) as f64 + 0.5) / SAMPLES as f64,
            ((k / SAMPLES) as f64 + 0.5) / SAMPLES as f64,
        );
        match shape {
            Shape::Parallelogram => Some(st),
            Shape::Triangle if st.x + st.y <= 1.0 => Some(st),
            // Reflected into the triangle: the grid's other half covers it again, evenly.
            Shape::Triangle => None,
        }
    })
}

/// Computes the reflectance of the nodes of `h` that have none yet. Does nothing for a root whose
/// reflectance is constant.
pub(super) fn extend(h: &mut Hierarchy, root: &ElementRoot) {
    let Some(map) = &root.reflectance else {
        return;
    };
    for i in h.reflectance.len()..h.nodes.len() {
        let r = of_node(map, root.shape, &h.nodes[i].map);
        h.reflectance.push(r);
    }
}

fn of_node(map: &ReflectanceMap, shape: Shape, node: &ChildMap) -> NodeReflectance {
    let (mean, deviation) = match shape {
        // Elements of a parallelogram root are boxes of its (s, t).
        Shape::Parallelogram => {
            let (a, b) = (node.apply(DVec2::ZERO), node.apply(DVec2::ONE));
            map.mean_over_box(a.min(b), a.max(b))
        }
        Shape::Triangle => map.mean_over_points(sample_points(shape).map(|st| node.apply(st))),
    };
    NodeReflectance { mean, deviation }
}

/// The reflectance of node `b`: its own for a varying root, the root's constant otherwise.
pub fn rho_of(h: &Hierarchy, root: &ElementRoot, b: usize) -> Rgb {
    h.reflectance.get(b).map_or(root.rho, |r| r.mean)
}

/// The deviation of node `b`'s reflectance from its mean (zero for a constant root).
pub fn deviation_of(h: &Hierarchy, b: usize) -> Rgb {
    h.reflectance.get(b).map_or([0.0; 3], |r| r.deviation)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_points_cover_the_shape_evenly() {
        let tri: Vec<DVec2> = sample_points(Shape::Triangle).collect();
        assert!(tri.iter().all(|p| p.x + p.y <= 1.0));
        assert_eq!(tri.len(), 136);
        // Their centroid is the triangle's, within the grid's staircase.
        let mean = tri.iter().fold(DVec2::ZERO, |a, &p| a + p) / tri.len() as f64;
        assert!((mean - DVec2::splat(1.0 / 3.0)).length() < 0.02);
    }
}

//! The bake pipeline without I/O: scene -> faces -> element roots -> visibility -> solve.
//!
//! Used by the CLI, the service and the tests so that all three solve exactly the same way.
//! Checks that the scene has something to solve (an emitter) before any work.

use crate::domain::{build_domains, DomainMode, ElementRoot, ExtendedDomain, Surface};
use crate::faces::{merge_planar_faces, FaceSet};
use crate::scene::LightKind;
use crate::scene::{Scene, SceneError};
use crate::solver::visibility::{bounding_planes, Visibility, ENDPOINT_EPSILON_REL};
use crate::solver::{solve, Progress, Solution, SolverParams};
use glam::DVec3;
use std::cmp::Ordering;
use std::sync::atomic::AtomicBool;

/// A scene prepared for solving: its faces, roots and occluders.
pub struct Prepared {
    pub faces: FaceSet,
    /// One per face side, with the range of its roots in `roots`.
    pub surfaces: Vec<Surface>,
    pub roots: Vec<ElementRoot>,
    /// Per face id: the extended domain of an extended face (its roots carry it as their `FaceMask`
    /// in extended mode).
    pub extended: Vec<Option<std::sync::Arc<ExtendedDomain>>>,
    pub visibility: Visibility,
    pub diagonal: f64,
}

/// Refuses scenes with nothing to solve (no emitter), with a reason for the user.
pub fn check_solvable(scene: &Scene) -> Result<(), SceneError> {
    if scene.triangles.is_empty() {
        return Err(SceneError::Unsolvable("the scene has no triangles".into()));
    }
    if scene.emissive_triangle_count() == 0 && scene.lights.is_empty() {
        return Err(SceneError::Unsolvable(
            "nothing to solve: no material emits (emissiveFactor is zero everywhere) and there are no KHR_lights_punctual lights".into(),
        ));
    }
    Ok(())
}

/// Builds planar faces, element roots and the visibility structure.
pub fn prepare(scene: &Scene, mode: DomainMode) -> Prepared {
    let faces = merge_planar_faces(scene);
    let domains = build_domains(scene, &faces, mode);
    let diagonal = scene.diagonal();
    let visibility = build_visibility(scene, &faces).visibility;
    Prepared {
        faces,
        surfaces: domains.surfaces,
        roots: domains.roots,
        extended: domains.extended,
        visibility,
        diagonal,
    }
}

/// The visibility structure a solve traces, and how it was made.
pub struct BuiltVisibility {
    pub visibility: Visibility,
    /// Faces left out of the BVH because their plane bounds the scene.
    pub bounding_faces: usize,
    /// Seconds spent finding them (`bounding_faces`).
    pub bounding_seconds: f64,
    /// Seconds spent building the BVH.
    pub bvh_seconds: f64,
}

/// The visibility structure of `prepare` (and so of every solve): a BVH over the faces' own
/// triangulations (the scene's triangles, some cut along contact lines, with welded corners),
/// less the faces that bound the scene, which can occlude nothing. `wavrad bench visibility`
/// times this same build.
pub fn build_visibility(scene: &Scene, faces: &FaceSet) -> BuiltVisibility {
    let diagonal = scene.diagonal();
    let start = std::time::Instant::now();
    let bounding = bounding_faces(scene, faces, diagonal);
    let bounding_seconds = start.elapsed().as_secs_f64();
    let occluders = faces
        .faces
        .iter()
        .zip(&bounding)
        .filter(|(_, &bounds)| !bounds)
        .flat_map(|(f, _)| f.triangulation.iter().map(move |t| (*t, f.id.0)));
    let start = std::time::Instant::now();
    let visibility = Visibility::new(occluders, diagonal);
    let bvh_seconds = start.elapsed().as_secs_f64();
    let bounding_faces = bounding.iter().filter(|&&b| b).count();
    tracing::debug!(
        bounding = bounding_faces,
        faces = faces.faces.len(),
        "faces left out of the occluders: they bound the scene"
    );
    BuiltVisibility {
        visibility,
        bounding_faces,
        bounding_seconds,
        bvh_seconds,
    }
}

/// Per face (in `faces.faces` order): does its plane bound the scene, so that it can occlude no
/// segment the solver traces (`visibility::bounding_planes`)? The largest faces are tested first.
fn bounding_faces(scene: &Scene, faces: &FaceSet, diagonal: f64) -> Vec<bool> {
    let mut endpoints: Vec<DVec3> = faces
        .faces
        .iter()
        .flat_map(|f| f.triangulation.iter().flatten().copied())
        .collect();
    let mut toward_lights = Vec::new();
    for light in &scene.lights {
        match light.kind {
            LightKind::Point { position } | LightKind::Spot { position, .. } => {
                endpoints.push(position)
            }
            LightKind::Directional { direction } => toward_lights.push(-direction),
        }
    }
    // Each vertex once (faces share them).
    endpoints.sort_by(|a, b| {
        a.to_array()
            .partial_cmp(&b.to_array())
            .unwrap_or(Ordering::Equal)
    });
    endpoints.dedup();
    let mut order: Vec<usize> = (0..faces.faces.len()).collect();
    order.sort_by(|&a, &b| faces.faces[b].area_m2.total_cmp(&faces.faces[a].area_m2));
    let planes: Vec<(DVec3, DVec3)> = order
        .iter()
        .map(|&i| {
            let f = &faces.faces[i];
            // (A face without an outline has no triangles: its verdict is moot.)
            (f.normal, f.outer.first().copied().unwrap_or_default())
        })
        .collect();
    let eps = ENDPOINT_EPSILON_REL * diagonal;
    let bounds = bounding_planes(&planes, &endpoints, &toward_lights, eps);
    let mut by_face = vec![false; faces.faces.len()];
    for (&i, b) in order.iter().zip(bounds) {
        by_face[i] = b;
    }
    by_face
}

/// Prepares and solves a scene.
pub fn bake(
    scene: &Scene,
    mode: DomainMode,
    params: SolverParams,
    cancel: &AtomicBool,
    observe: &mut dyn FnMut(&Progress),
) -> Result<(Prepared, Solution), SceneError> {
    check_solvable(scene)?;
    let mut prepared = prepare(scene, mode);
    let roots = std::mem::take(&mut prepared.roots);
    let solution = solve(
        roots,
        &scene.lights,
        &prepared.visibility,
        prepared.diagonal,
        params,
        cancel,
        observe,
    );
    prepared.roots = solution.roots.clone();
    Ok((prepared, solution))
}

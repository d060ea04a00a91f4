//! The bake pipeline without I/O: scene -> faces -> element roots -> visibility -> solve.
//!
//! Used by the CLI, the service and the tests so that all three solve exactly the same way.
//! Checks that the scene has something to solve (an emitter) before any work.

use crate::domain::{build_domains, DomainMode, ElementRoot, ExtendedDomain, Surface};
use crate::faces::{merge_planar_faces, FaceSet};
use crate::scene::{Scene, SceneError};
use crate::solver::{solve, visibility::Visibility, Progress, Solution, SolverParams};
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
    // Faces occlude with their own triangulations: the scene's triangles, some cut along contact
    // lines, with welded corners.
    let occluders = faces
        .faces
        .iter()
        .flat_map(|f| f.triangulation.iter().map(move |t| (*t, f.id.0)));
    let diagonal = scene.diagonal();
    let visibility = Visibility::new(occluders, diagonal);
    Prepared {
        faces,
        surfaces: domains.surfaces,
        roots: domains.roots,
        extended: domains.extended,
        visibility,
        diagonal,
    }
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

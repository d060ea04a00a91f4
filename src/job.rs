//! A bake job: validated parameters (the solver options of docs/contract.md, same names on the command line
//! and over HTTP), and `run_job`, which solves a loaded scene and writes every output file.
//!
//! Both the CLI (`wavrad solve`) and the service run [`run_job_keeping_solution`] (the CLI through
//! [`run_job_with_probes`]), so they produce the same files; the service keeps the solution to
//! answer probe requests.

use crate::fsutil::write_atomic;
use crate::output::probes::{evaluate_probes, ProbePoint, ProbeValue};
use crate::output::solution_file::{self, SolutionFileError};
use crate::output::{write_outputs, AtlasSettings, OutputOptions};
use crate::pipeline::{bake, prepare};
use crate::scene::{Scene, SceneError};
use crate::solver::{
    Progress, Quantity, Solution, SolverParams, StopReason, DEFAULT_TOLERANCE, FAR_VERDICT_BYTES,
    NEAR_VERDICT_BYTES,
};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// Where radiosity lives: the paper's extended domains, or the tessellated baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum DomainMode {
    #[default]
    Extended,
    Tessellated,
}

/// What lightmaps and probes hold (serialisable twin of [`Quantity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum QuantityParam {
    #[default]
    Radiance,
    Irradiance,
}

/// Job parameters with the names of docs/contract.md and defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JobParams {
    pub order: usize,
    pub domain: DomainMode,
    pub target_unshot: f64,
    pub tolerance: f64,
    pub max_seconds: Option<f64>,
    pub texels_per_meter: Option<f64>,
    pub quantity: QuantityParam,
    pub indirect_only: bool,
    pub exr_float: bool,
    /// Texels of gutter around each atlas rectangle (`output::atlas`: 4 keeps 4 mip levels apart).
    pub gutter: u32,
    /// Largest atlas page side, texels.
    pub atlas_max_size: u32,
    /// Atlas page sides are powers of two.
    pub atlas_pow2: bool,
}

impl Default for JobParams {
    fn default() -> Self {
        JobParams {
            order: 2,
            domain: DomainMode::Extended,
            target_unshot: 1e-3,
            tolerance: DEFAULT_TOLERANCE,
            max_seconds: None,
            texels_per_meter: None,
            quantity: QuantityParam::Radiance,
            indirect_only: false,
            exr_float: false,
            gutter: crate::output::atlas::DEFAULT_GUTTER,
            atlas_max_size: crate::output::atlas::DEFAULT_MAX_PAGE_SIZE,
            atlas_pow2: false,
        }
    }
}

/// Largest lightmap density accepted (texels per metre), to bound atlas memory.
pub const MAX_TEXELS_PER_METER: f64 = 1e6;

impl JobParams {
    /// Checks every parameter; the error names the parameter and the accepted range.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=3).contains(&self.order) {
            return Err(format!("order must be 1, 2 or 3 (got {})", self.order));
        }
        if !(self.target_unshot.is_finite() && self.target_unshot > 0.0 && self.target_unshot < 1.0)
        {
            return Err(format!(
                "target_unshot must be in (0, 1) (got {})",
                self.target_unshot
            ));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(format!(
                "tolerance must be in (0, 1) (got {})",
                self.tolerance
            ));
        }
        if let Some(s) = self.max_seconds {
            if !(s.is_finite() && s > 0.0) {
                return Err(format!(
                    "max_seconds must be a positive number of seconds (got {s})"
                ));
            }
        }
        if let Some(d) = self.texels_per_meter {
            if !(d.is_finite() && d > 0.0 && d <= MAX_TEXELS_PER_METER) {
                return Err(format!(
                    "texels_per_meter must be in (0, {MAX_TEXELS_PER_METER}] (got {d})"
                ));
            }
        }
        self.atlas_settings().validate()
    }

    pub fn atlas_settings(&self) -> AtlasSettings {
        AtlasSettings {
            gutter: self.gutter,
            max_page_size: self.atlas_max_size,
            pow2: self.atlas_pow2,
        }
    }

    pub fn domain_mode(&self) -> crate::domain::DomainMode {
        match self.domain {
            DomainMode::Extended => crate::domain::DomainMode::Extended,
            DomainMode::Tessellated => crate::domain::DomainMode::Tessellated,
        }
    }

    pub fn solver_params(&self) -> SolverParams {
        SolverParams {
            order: self.order,
            target_unshot: self.target_unshot,
            tolerance: self.tolerance,
            max_seconds: self.max_seconds,
            quantity: match self.quantity {
                QuantityParam::Radiance => Quantity::Radiance,
                QuantityParam::Irradiance => Quantity::Irradiance,
            },
            indirect_only: self.indirect_only,
            ..SolverParams::default()
        }
    }
}

/// Scene, faces and visibility structure per input triangle (bytes), measured order of magnitude.
const BYTES_PER_TRIANGLE: u64 = 512;
/// Elements a triangle's root is refined into on average at the default tolerance (a generous
/// figure: the sample scenes stay below 2).
const ELEMENTS_PER_TRIANGLE: u64 = 8;
/// Per element: tree node (map, links) besides its coefficients.
const BYTES_PER_NODE: u64 = 64;
/// The near links' kept verdicts per triangle (a generous figure: the 70k-triangle level keeps
/// about a third of it), within [`NEAR_VERDICT_BYTES`].
const NEAR_VERDICT_BYTES_PER_TRIANGLE: u64 = 16384;

/// A rough upper estimate of a solve's memory (bytes): per triangle, its share of scene, faces
/// and visibility structure, plus `ELEMENTS_PER_TRIANGLE` elements each holding four coefficient
/// arrays (irradiance, direct, unshot, gathered) of `order^2` functions in three channels of f64;
/// and the far links' verdicts (two bits per pair of roots, at most two roots per triangle,
/// within [`FAR_VERDICT_BYTES`]) and the near links' (`NEAR_VERDICT_BYTES_PER_TRIANGLE`, within
/// [`NEAR_VERDICT_BYTES`]).
pub fn estimated_memory_bytes(triangles: usize, order: usize) -> u64 {
    let functions = (order * order) as u64;
    let element = functions * 4 * 3 * 8 + BYTES_PER_NODE;
    let t = triangles as u64;
    let far = t.saturating_mul(t).min(FAR_VERDICT_BYTES as u64);
    let near = t
        .saturating_mul(NEAR_VERDICT_BYTES_PER_TRIANGLE)
        .min(NEAR_VERDICT_BYTES as u64);
    t.saturating_mul(BYTES_PER_TRIANGLE + ELEMENTS_PER_TRIANGLE * element)
        .saturating_add(far)
        .saturating_add(near)
}

/// Why a job failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// The scene cannot be solved (HTTP 422, exit code 2).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Writing outputs failed (HTTP 500, exit code 1).
    #[error("writing outputs failed: {0}")]
    Io(#[from] std::io::Error),
}

/// What a finished job reports.
#[derive(Debug, Clone)]
pub struct JobOutcome {
    /// The full result.json document (`Null` for a cancelled job, which writes no outputs).
    pub result: serde_json::Value,
    pub stop_reason: StopReason,
}

/// Solves `scene` with `params` and writes result.json, lightmap.exr and convergence.csv to `out_dir`.
pub fn run_job(
    scene: &Scene,
    params: &JobParams,
    out_dir: &Path,
    cancel: &AtomicBool,
    observe: &mut dyn FnMut(&Progress),
) -> Result<JobOutcome, JobError> {
    run_job_with_probes(scene, params, None, out_dir, cancel, observe)
}

/// A finished solution kept to answer probe requests after the job (`POST /v1/jobs/{id}/probes`),
/// in memory and, through [`ProbeSource::save`] and [`ProbeSource::load`], in `solution.bin`.
#[derive(Debug)]
pub struct ProbeSource {
    solution: Solution,
    diagonal: f64,
    mode: crate::domain::DomainMode,
}

impl ProbeSource {
    /// The requested quantity at each probe, as `probe_values.json` holds it.
    pub fn evaluate(&self, probes: &[ProbePoint]) -> Vec<ProbeValue> {
        evaluate_probes(&self.solution, probes, self.diagonal)
    }

    /// Writes the solution to `path` atomically ([`solution_file`]).
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        solution_file::save(path, &self.solution, self.mode)
    }

    /// The solution saved at `path` by [`ProbeSource::save`] for `scene`, the job's scene (its
    /// element roots are rebuilt from it and checked against the file).
    pub fn load(path: &Path, scene: &Scene) -> Result<ProbeSource, SolutionFileError> {
        let saved = solution_file::read(path)?;
        let mode = saved.mode();
        let prepared = prepare(scene, mode);
        Ok(ProbeSource {
            solution: saved.attach(prepared.roots)?,
            diagonal: prepared.diagonal,
            mode,
        })
    }
}

/// [`run_job`], plus `probe_values.json` when probes are given.
pub fn run_job_with_probes(
    scene: &Scene,
    params: &JobParams,
    probes: Option<&[ProbePoint]>,
    out_dir: &Path,
    cancel: &AtomicBool,
    observe: &mut dyn FnMut(&Progress),
) -> Result<JobOutcome, JobError> {
    run_job_keeping_solution(scene, params, probes, out_dir, cancel, observe)
        .map(|(outcome, _)| outcome)
}

/// [`run_job_with_probes`], also returning the solution (None for a cancelled job) so that later
/// probe requests can be answered from it.
pub fn run_job_keeping_solution(
    scene: &Scene,
    params: &JobParams,
    probes: Option<&[ProbePoint]>,
    out_dir: &Path,
    cancel: &AtomicBool,
    observe: &mut dyn FnMut(&Progress),
) -> Result<(JobOutcome, Option<ProbeSource>), JobError> {
    let (prepared, solution) = bake(
        scene,
        params.domain_mode(),
        params.solver_params(),
        cancel,
        observe,
    )?;
    let stop_reason = solution.stats.stop_reason.unwrap_or(StopReason::Converged);
    if stop_reason == StopReason::Cancelled {
        // A cancelled job's outputs are not wanted: return at once.
        return Ok((
            JobOutcome {
                result: serde_json::Value::Null,
                stop_reason,
            },
            None,
        ));
    }
    std::fs::create_dir_all(out_dir)?;
    let options = OutputOptions {
        texels_per_meter: params.texels_per_meter,
        atlas: params.atlas_settings(),
        exr_float: params.exr_float,
        domain: params.domain_mode(),
        params: serde_json::to_value(params).unwrap_or(serde_json::Value::Null),
    };
    let result = write_outputs(out_dir, scene, &prepared, &solution, &options)?;
    if let Some(probes) = probes {
        let values = evaluate_probes(&solution, probes, prepared.diagonal);
        let text = serde_json::to_vec_pretty(&values).map_err(std::io::Error::other)?;
        write_atomic(&out_dir.join("probe_values.json"), &text)?;
    }
    Ok((
        JobOutcome {
            result,
            stop_reason,
        },
        Some(ProbeSource {
            solution,
            diagonal: prepared.diagonal,
            mode: params.domain_mode(),
        }),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate counts the links' kept verdicts: the far links' two bits per pair of at
    /// most two roots per triangle, the near links' bytes per triangle, each never more than
    /// its budget.
    #[test]
    fn the_memory_estimate_counts_the_links_verdicts() {
        let per_triangle = |order: usize| {
            BYTES_PER_TRIANGLE + ELEMENTS_PER_TRIANGLE * (order * order * 96 + 64) as u64
        };
        assert_eq!(
            estimated_memory_bytes(100, 2),
            100 * per_triangle(2) + 10_000 + 100 * NEAR_VERDICT_BYTES_PER_TRIANGLE
        );
        let level = 70_754;
        assert_eq!(
            estimated_memory_bytes(level, 3),
            level as u64 * per_triangle(3)
                + FAR_VERDICT_BYTES as u64
                + (level as u64 * NEAR_VERDICT_BYTES_PER_TRIANGLE).min(NEAR_VERDICT_BYTES as u64)
        );
        let city = 1_000_000;
        assert_eq!(
            estimated_memory_bytes(city, 2),
            city as u64 * per_triangle(2) + FAR_VERDICT_BYTES as u64 + NEAR_VERDICT_BYTES as u64
        );
        assert_eq!(estimated_memory_bytes(usize::MAX, 2), u64::MAX);
    }
}

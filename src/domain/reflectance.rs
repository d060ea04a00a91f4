//! Reflectance and emission that vary over a face: its material's factors times its textures,
//! read through the texture coordinates of the scene triangle each piece of the face came from.
//!
//! Owns [`FaceTexture`] (the texture at any point of one face) and [`ReflectanceMap`] (one root's
//! reflectance sampled on a `RASTER x RASTER` grid of its `(s, t)`, the cells whose centre lies on
//! the face; the solver averages it over each element's footprint).
//!
//! Invariants: a face whose every piece maps into texels of one colour (a palette texture, a
//! uniform cell) is uniform: its reflectance and emission are exactly `factor x colour` and it gets
//! no map ([`FaceTexture::uniform`]); the texture coordinates of a point are those of its piece's
//! scene triangle (pieces cut along contacts lie inside it), interpolated linearly; a point on no
//! piece (a gap of rounding, a domain point off the face) reads the nearest piece.
//! Pinned by `tests/textures.rs` (a ramp face's reflected power, the textured twin of the Kenney
//! building) and the unit tests below.

use super::Frame;
use crate::faces::{Face, FaceSet};
use crate::scene::{Rgb, Scene, Texture};
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// Most cells per side of a root's reflectance raster.
pub const RASTER: usize = 32;

/// One piece of a face in the face's plane coordinates, with the affine map from plane
/// coordinates to each texture's coordinates.
#[derive(Debug, Clone)]
struct Piece {
    corners: [DVec2; 3],
    /// `uv(p) = origin + m * (p - corners[0])` for base colour (0) and emission (1).
    uv: [(DVec2, [DVec2; 2]); 2],
}

/// The textured reflectance and emission of one face.
#[derive(Debug, Clone)]
pub struct FaceTexture {
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    pieces: Vec<Piece>,
    grid: PieceGrid,
    /// `(factor, texture)` for base colour and emission; `None` when that slot has no texture.
    slots: [Option<(Rgb, Arc<Texture>)>; 2],
    factors: [Rgb; 2],
    /// Set when both quantities are the same everywhere on the face: (rho, L_e).
    uniform: Option<(Rgb, Rgb)>,
    /// How many texels the face spans along its longer texture axis (the largest of its textures).
    texel_span: f64,
}

/// Pieces by cell of a uniform grid over the face's plane box.
#[derive(Debug, Clone)]
struct PieceGrid {
    lo: DVec2,
    cell: DVec2,
    n: [usize; 2],
    cells: Vec<Vec<u32>>,
}

impl PieceGrid {
    fn new(pieces: &[Piece]) -> Self {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for p in pieces {
            for c in p.corners {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let side = ((pieces.len() as f64).sqrt().ceil() as usize).clamp(1, 64);
        let n = [side, side];
        let cell = ((hi - lo) / side as f64).max(DVec2::splat(1e-300));
        let mut cells = vec![Vec::new(); side * side];
        for (i, p) in pieces.iter().enumerate() {
            let (a, b) = p.corners.iter().fold(
                (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                |(a, b), &c| (a.min(c), b.max(c)),
            );
            let (x0, y0) = Self::index_of(lo, cell, n, a);
            let (x1, y1) = Self::index_of(lo, cell, n, b);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    cells[y * side + x].push(i as u32);
                }
            }
        }
        PieceGrid { lo, cell, n, cells }
    }

    fn index_of(lo: DVec2, cell: DVec2, n: [usize; 2], p: DVec2) -> (usize, usize) {
        let f = (p - lo) / cell;
        let clamp = |v: f64, n: usize| {
            if v.is_finite() {
                (v.max(0.0) as usize).min(n - 1)
            } else {
                0
            }
        };
        (clamp(f.x, n[0]), clamp(f.y, n[1]))
    }
}

/// Barycentric coordinates of `p` in triangle `c` (plane), `None` when degenerate.
fn barycentric(c: &[DVec2; 3], p: DVec2) -> Option<[f64; 3]> {
    let d = (c[1] - c[0]).perp_dot(c[2] - c[0]);
    if d.abs() < 1e-300 || !d.is_finite() {
        return None;
    }
    let b1 = (p - c[0]).perp_dot(c[2] - c[0]) / d;
    let b2 = (c[1] - c[0]).perp_dot(p - c[0]) / d;
    Some([1.0 - b1 - b2, b1, b2])
}

/// Distance from `p` to triangle `c` (0 inside).
fn distance_to_triangle(c: &[DVec2; 3], p: DVec2) -> f64 {
    if let Some(b) = barycentric(c, p) {
        if b.iter().all(|&x| x >= 0.0) {
            return 0.0;
        }
    }
    (0..3)
        .map(|i| {
            let (a, b) = (c[i], c[(i + 1) % 3]);
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_squared().max(1e-300)).clamp(0.0, 1.0);
            (a + ab * t).distance(p)
        })
        .fold(f64::INFINITY, f64::min)
}

impl FaceTexture {
    /// The face's texture, or `None` when its material has no texture (its factors are exact).
    pub fn new(scene: &Scene, faces: &FaceSet, face: &Face) -> Option<FaceTexture> {
        let material = scene.materials.get(face.material as usize)?;
        if !material.has_texture() || scene.texcoords.len() != scene.triangles.len() {
            return None;
        }
        let n = face.normal;
        let e1 = n.any_orthonormal_vector();
        let e2 = n.cross(e1);
        let origin = face.outer.first().copied().unwrap_or(DVec3::ZERO);
        let to_plane = |p: DVec3| DVec2::new((p - origin).dot(e1), (p - origin).dot(e2));
        let slots = [material.base_color_texture, material.emissive_texture]
            .map(|slot| slot.and_then(|s| scene.textures.get(s.texture as usize).cloned()));
        let factors = [material.rho, material.emission];
        let mut pieces = Vec::with_capacity(face.triangles.len());
        for (k, &piece) in face.triangles.iter().enumerate() {
            let Some(&source) = faces.piece_source.get(piece as usize) else {
                continue;
            };
            let (Some(tri), Some(tc)) = (
                scene.triangles.get(source as usize),
                scene.texcoords.get(source as usize),
            ) else {
                continue;
            };
            let Some(corners) = face.triangulation.get(k) else {
                continue;
            };
            // Affine map from the plane to texture coordinates, from the scene triangle's corners.
            let src = tri.vertices.map(to_plane);
            let d = (src[1] - src[0]).perp_dot(src[2] - src[0]);
            let uv = [tc.base_color, tc.emissive].map(|uv| {
                if d.abs() < 1e-300 || !d.is_finite() {
                    return (uv[0], [DVec2::ZERO; 2]);
                }
                // Columns: d(uv)/dx and d(uv)/dy of the plane coordinates.
                let (p1, p2) = (src[1] - src[0], src[2] - src[0]);
                let (q1, q2) = (uv[1] - uv[0], uv[2] - uv[0]);
                let inv = 1.0 / d;
                let dx = (q1 * p2.y - q2 * p1.y) * inv;
                let dy = (q2 * p1.x - q1 * p2.x) * inv;
                // Re-based on this piece's first corner.
                let c0 = to_plane(corners[0]) - src[0];
                (uv[0] + dx * c0.x + dy * c0.y, [dx, dy])
            });
            pieces.push(Piece {
                corners: corners.map(to_plane),
                uv,
            });
        }
        if pieces.is_empty() {
            return None;
        }
        let grid = PieceGrid::new(&pieces);
        let mut face_texture = FaceTexture {
            origin,
            e1,
            e2,
            pieces,
            grid,
            slots: [
                slots[0].clone().map(|t| (factors[0], t)),
                slots[1].clone().map(|t| (factors[1], t)),
            ],
            factors,
            uniform: None,
            texel_span: 0.0,
        };
        face_texture.uniform = face_texture.uniform_values();
        face_texture.texel_span = face_texture.span();
        Some(face_texture)
    }

    /// The texel extent of the face's texture coordinates along the longer axis.
    fn span(&self) -> f64 {
        let mut span: f64 = 0.0;
        for (k, slot) in self.slots.iter().enumerate() {
            let Some((_, texture)) = slot else { continue };
            let mut lo = DVec2::splat(f64::INFINITY);
            let mut hi = DVec2::splat(f64::NEG_INFINITY);
            for p in &self.pieces {
                for c in p.corners {
                    let uv = self.uv_in(p, k, c);
                    lo = lo.min(uv);
                    hi = hi.max(uv);
                }
            }
            let size = DVec2::new(f64::from(texture.width), f64::from(texture.height));
            let extent = (hi - lo) * size;
            if extent.is_finite() {
                span = span.max(extent.max_element());
            }
        }
        span
    }

    /// (rho, L_e) when every piece reads one colour of each texture.
    fn uniform_values(&self) -> Option<(Rgb, Rgb)> {
        let mut out = self.factors;
        for (k, slot) in self.slots.iter().enumerate() {
            let Some((factor, texture)) = slot else {
                continue;
            };
            let mut colour: Option<[f32; 3]> = None;
            for p in &self.pieces {
                let uvs = p.corners.map(|c| self.uv_in(p, k, c));
                let lo = uvs[0].min(uvs[1]).min(uvs[2]);
                let hi = uvs[0].max(uvs[1]).max(uvs[2]);
                let c = texture.uniform_over(lo, hi)?;
                if colour.is_some_and(|x| x != c) {
                    return None;
                }
                colour = Some(c);
            }
            let c = colour?;
            out[k] = [0, 1, 2].map(|ch| factor[ch] * f64::from(c[ch]));
        }
        out[0] = out[0].map(|x| x.clamp(0.0, 1.0));
        Some((out[0], out[1]))
    }

    fn uv_in(&self, piece: &Piece, slot: usize, p: DVec2) -> DVec2 {
        let (o, [dx, dy]) = piece.uv[slot];
        let d = p - piece.corners[0];
        o + dx * d.x + dy * d.y
    }

    /// (rho, L_e) everywhere on the face, when they do not vary.
    pub fn uniform(&self) -> Option<(Rgb, Rgb)> {
        self.uniform
    }

    /// The piece containing plane point `p`, or the nearest one: the grid's cells are searched in
    /// rings around `p`'s, until no nearer piece can lie further out.
    fn piece_at(&self, p: DVec2) -> &Piece {
        let g = &self.grid;
        let (cx, cy) = PieceGrid::index_of(g.lo, g.cell, g.n, p);
        let (cx, cy) = (cx as i64, cy as i64);
        let mut best = (f64::INFINITY, 0usize);
        let rings = g.n[0].max(g.n[1]) as i64;
        for r in 0..=rings {
            for y in (cy - r)..=(cy + r) {
                for x in (cx - r)..=(cx + r) {
                    let on_ring = (y - cy).abs() == r || (x - cx).abs() == r;
                    if !on_ring || x < 0 || y < 0 || x >= g.n[0] as i64 || y >= g.n[1] as i64 {
                        continue;
                    }
                    for &i in &g.cells[y as usize * g.n[0] + x as usize] {
                        let d = distance_to_triangle(&self.pieces[i as usize].corners, p);
                        if d < best.0 || (d == best.0 && (i as usize) < best.1) {
                            best = (d, i as usize);
                        }
                    }
                }
            }
            // Cells of the next ring are at least r cells away from p (p inside its own cell, or
            // clamped onto the grid from outside, which only moves them further).
            if best.0 == 0.0 || best.0 <= r as f64 * g.cell.min_element() {
                break;
            }
        }
        &self.pieces[best.1]
    }

    /// Reflectance and emitted radiance at world point `x` (projected onto the face's plane).
    pub fn at(&self, x: DVec3) -> (Rgb, Rgb) {
        if let Some(u) = self.uniform {
            return u;
        }
        let p = DVec2::new(
            (x - self.origin).dot(self.e1),
            (x - self.origin).dot(self.e2),
        );
        let piece = self.piece_at(p);
        let mut out = self.factors;
        for (k, slot) in self.slots.iter().enumerate() {
            if let Some((factor, texture)) = slot {
                let c = texture.sample(self.uv_in(piece, k, p));
                out[k] = [0, 1, 2].map(|ch| factor[ch] * c[ch]);
            }
        }
        out[0] = out[0].map(|x| x.clamp(0.0, 1.0));
        (out[0], out[1])
    }
}

/// One root's reflectance on a raster of its `(s, t)`: each cell's mean over sub-samples on the
/// face (supersampled at about the texture's own rate, up to [`MAX_SUBSAMPLES`] per side).
#[derive(Debug, Clone)]
pub struct ReflectanceMap {
    pub texture: Arc<FaceTexture>,
    /// Cells per side: the face's texel span, within `2..=RASTER`.
    n: usize,
    /// Per cell (row-major, `t` rows), rho; NaN off the face (or off a triangle).
    cells: Vec<[f32; 3]>,
    /// The mean of the cells on the face.
    pub mean: Rgb,
}

/// Most sub-samples per side of a raster cell.
pub const MAX_SUBSAMPLES: usize = 4;

impl ReflectanceMap {
    /// Samples `texture` over the cells of a root framed by `frame`, at the sub-sample points for
    /// which `on_face` holds; returns the map and the mean emitted radiance. `None` when no
    /// sub-sample is on the face. Cells per side: the face's texel span, at most `max_cells` (and
    /// within `2..=RASTER`).
    pub fn new(
        texture: Arc<FaceTexture>,
        frame: &Frame,
        max_cells: f64,
        on_face: impl Fn(DVec2) -> bool,
    ) -> Option<(ReflectanceMap, Rgb)> {
        let span = texture.texel_span;
        let n = (span.min(max_cells).ceil() as usize).clamp(2, RASTER);
        let k = ((span / n as f64).ceil() as usize).clamp(1, MAX_SUBSAMPLES);
        let mut cells = Vec::with_capacity(n * n);
        let (mut rho_sum, mut emit_sum, mut count) = ([0.0; 3], [0.0; 3], 0usize);
        for j in 0..n {
            for i in 0..n {
                let (mut cell, mut cell_count) = ([0.0; 3], 0usize);
                for sj in 0..k {
                    for si in 0..k {
                        let st = DVec2::new(
                            (i as f64 + (si as f64 + 0.5) / k as f64) / n as f64,
                            (j as f64 + (sj as f64 + 0.5) / k as f64) / n as f64,
                        );
                        if !on_face(st) {
                            continue;
                        }
                        let (rho, emission) = texture.at(frame.point(st));
                        for ch in 0..3 {
                            cell[ch] += rho[ch];
                            emit_sum[ch] += emission[ch];
                        }
                        cell_count += 1;
                    }
                }
                if cell_count == 0 {
                    cells.push([f32::NAN; 3]);
                    continue;
                }
                for ch in 0..3 {
                    rho_sum[ch] += cell[ch];
                }
                count += cell_count;
                cells.push(cell.map(|c| (c / cell_count as f64) as f32));
            }
        }
        if count == 0 {
            return None;
        }
        let mean = rho_sum.map(|x| x / count as f64);
        let emission = emit_sum.map(|x| x / count as f64);
        Some((
            ReflectanceMap {
                texture,
                n,
                cells,
                mean,
            },
            emission,
        ))
    }

    fn cell(&self, x: usize, y: usize) -> Option<Rgb> {
        let c = self.cells[y * self.n + x];
        (!c[0].is_nan()).then(|| c.map(f64::from))
    }

    /// rho of the cell holding root point `st`, `None` off the face.
    pub fn cell_at(&self, st: DVec2) -> Option<Rgb> {
        let n = self.n;
        let idx = |v: f64| -> usize {
            if v.is_finite() {
                ((v * n as f64).max(0.0) as usize).min(n - 1)
            } else {
                0
            }
        };
        self.cell(idx(st.x), idx(st.y))
    }

    /// The mean and the mean absolute deviation (per channel) of rho over the cells holding the
    /// given root points (those on the face); the root's mean and no deviation when none is.
    pub fn mean_over_points(&self, points: impl Iterator<Item = DVec2> + Clone) -> (Rgb, Rgb) {
        self.weighted_mean(points.filter_map(|st| self.cell_at(st).map(|v| (v, 1.0))))
    }

    /// The mean and the mean absolute deviation of rho over the box `[lo, hi]` of root
    /// coordinates: each cell on the face weighted by the area it shares with the box (the raster
    /// read as piecewise constant, so a box of whole cells gets exactly their mean).
    pub fn mean_over_box(&self, lo: DVec2, hi: DVec2) -> (Rgb, Rgb) {
        let cells_per_side = self.n;
        let n = cells_per_side as f64;
        let range = |a: f64, b: f64| {
            let i0 = ((a * n).floor().max(0.0) as usize).min(cells_per_side - 1);
            let i1 = ((b * n).ceil().max(1.0) as usize).min(cells_per_side);
            (i0, i1.max(i0 + 1))
        };
        if !(lo.is_finite() && hi.is_finite()) {
            return (self.mean, [0.0; 3]);
        }
        let (x0, x1) = range(lo.x, hi.x);
        let (y0, y1) = range(lo.y, hi.y);
        let overlap = |i: usize, a: f64, b: f64| {
            let (c0, c1) = (i as f64 / n, (i + 1) as f64 / n);
            (b.min(c1) - a.max(c0)).max(0.0)
        };
        let cells = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y)));
        self.weighted_mean(cells.filter_map(|(x, y)| {
            let w = overlap(x, lo.x, hi.x) * overlap(y, lo.y, hi.y);
            let v = self.cell(x, y)?;
            (w > 0.0).then_some((v, w))
        }))
    }

    fn weighted_mean(&self, values: impl Iterator<Item = (Rgb, f64)> + Clone) -> (Rgb, Rgb) {
        let (mut mean, mut total) = ([0.0; 3], 0.0);
        for (v, w) in values.clone() {
            total += w;
            for ch in 0..3 {
                mean[ch] += w * v[ch];
            }
        }
        if total <= 0.0 {
            return (self.mean, [0.0; 3]);
        }
        let mean = mean.map(|m| m / total);
        let mut dev = [0.0; 3];
        for (v, w) in values {
            for ch in 0..3 {
                dev[ch] += w * (v[ch] - mean[ch]).abs() / total;
            }
        }
        (mean, dev)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_and_distance_agree_with_hand_values() {
        let c = [DVec2::ZERO, DVec2::X, DVec2::Y];
        let b = barycentric(&c, DVec2::new(0.25, 0.25)).unwrap();
        assert!((b[0] - 0.5).abs() < 1e-15 && (b[1] - 0.25).abs() < 1e-15);
        assert_eq!(distance_to_triangle(&c, DVec2::new(0.1, 0.1)), 0.0);
        assert!((distance_to_triangle(&c, DVec2::new(-1.0, 0.5)) - 1.0).abs() < 1e-15);
        assert!((distance_to_triangle(&c, DVec2::new(1.0, 1.0)) - 0.5f64.sqrt()).abs() < 1e-12);
    }
}

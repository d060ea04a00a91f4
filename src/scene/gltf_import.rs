//! glTF/GLB import: bytes in, a validated [`Scene`] out, every problem reported with its place.
//!
//! Nothing here panics on bad input: the GLB container is checked before the `gltf` crate sees it,
//! accessor reads go through bounds-checked readers, node graphs are walked with a visited set
//! (cycles are reported, not followed), and the whole parse runs under `catch_unwind` as a last line.

pub use super::buffers::ExternalFiles;
use super::buffers::{load_buffers, read_uri};
use super::error::{Problem, SceneError};
use super::gltf_textures::{read_textures, read_uv_sets, texture_slot};
use super::{
    Camera, GltfSource, LightKind, Material, MeshInstance, PunctualLight, Scene, Triangle,
    TriangleSource, TriangleTexcoords,
};
use glam::{DMat4, DVec3};
use std::path::Path;

/// Deepest node nesting followed; deeper is reported as a problem (protects the stack).
const MAX_NODE_DEPTH: usize = 256;

/// Loads a scene from a file; external buffers resolve next to the file.
pub fn load_scene_from_path(path: &Path, max_triangles: usize) -> Result<Scene, SceneError> {
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::External(format!("cannot read '{}': {e}", path.display())))?;
    let dir = path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| ".".into());
    load_scene(&bytes, &ExternalFiles::Directory(dir), max_triangles)
}

/// Loads a scene from GLB or glTF JSON bytes.
pub fn load_scene(
    bytes: &[u8],
    external: &ExternalFiles,
    max_triangles: usize,
) -> Result<Scene, SceneError> {
    check_container(bytes)?;
    let result = std::panic::catch_unwind(|| load_scene_unchecked(bytes, external, max_triangles));
    match result {
        Ok(r) => r,
        Err(_) => Err(SceneError::Unreadable(
            "the glTF parser failed on this file (it is malformed)".into(),
        )),
    }
}

/// Checks the GLB header and chunk table, or that a non-GLB file at least looks like JSON.
fn check_container(bytes: &[u8]) -> Result<(), SceneError> {
    if bytes.is_empty() {
        return Err(SceneError::Unreadable("the file is empty".into()));
    }
    if bytes.starts_with(b"glTF") {
        if bytes.len() < 20 {
            return Err(SceneError::Unreadable(format!(
                "GLB is truncated: {} bytes, shorter than its 12-byte header and first chunk header",
                bytes.len()
            )));
        }
        let u32_at =
            |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
        let version = u32_at(4);
        if version != 2 {
            return Err(SceneError::Unreadable(format!(
                "GLB version {version} is not supported (only glTF 2.0)"
            )));
        }
        let length = u32_at(8) as usize;
        if length != bytes.len() {
            return Err(SceneError::Unreadable(format!(
                "GLB header says {length} bytes but the file has {} (truncated or padded file)",
                bytes.len()
            )));
        }
        let mut offset = 12;
        let mut chunk = 0;
        while offset < length {
            if offset + 8 > length {
                return Err(SceneError::Unreadable(format!(
                    "GLB chunk {chunk} header runs past the end of the file"
                )));
            }
            let chunk_len = u32_at(offset) as usize;
            let end = offset + 8 + chunk_len;
            if end > length {
                return Err(SceneError::Unreadable(format!(
                    "GLB chunk {chunk} declares {chunk_len} bytes, past the end of the file (truncated)"
                )));
            }
            offset = end;
            chunk += 1;
        }
        return Ok(());
    }
    let first = bytes
        .iter()
        .find(|b| !(b.is_ascii_whitespace() || **b == 0xEF || **b == 0xBB || **b == 0xBF));
    if first != Some(&b'{') {
        return Err(SceneError::Unreadable(
            "neither a GLB (magic 'glTF') nor glTF JSON (starting with '{')".into(),
        ));
    }
    Ok(())
}

/// Every accessor index of a primitive (attributes, indices, morph targets) is in range.
fn check_accessor_indices(root: &gltf::json::Root) -> Result<(), SceneError> {
    let count = root.accessors.len();
    let mut bad = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let place = format!("meshes[{m}].primitives[{p}]");
            for (semantic, index) in &primitive.attributes {
                if index.value() >= count {
                    bad.push(format!("{place}.attributes.{semantic:?}"));
                }
            }
            if primitive.indices.is_some_and(|i| i.value() >= count) {
                bad.push(format!("{place}.indices"));
            }
            for (t, target) in primitive.targets.iter().flatten().enumerate() {
                let indices = [&target.positions, &target.normals, &target.tangents];
                if indices
                    .iter()
                    .any(|i| i.is_some_and(|i| i.value() >= count))
                {
                    bad.push(format!("{place}.targets[{t}]"));
                }
            }
        }
    }
    if !bad.is_empty() {
        return Err(SceneError::Unreadable(format!(
            "invalid glTF: {}: accessor index out of bounds (the file has {count} accessor(s))",
            bad.join(", ")
        )));
    }
    // gltf's readers compute `count - 1` and assume a stride of at least one element (a panic in
    // checked builds, found by fuzzing): the spec's own rules, checked here first.
    use gltf::json::validation::Checked;
    // The readers also take the accessor's type on trust: POSITION is read as VEC3 floats (a
    // VEC2 accessor fails a size assertion, found by fuzzing) and indices as unsigned integers
    // (a float index accessor reaches an `unreachable!`). The spec's types for both, checked here.
    use gltf::json::accessor::{ComponentType, Type};
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let place = format!("meshes[{m}].primitives[{p}]");
            let accessor =
                |i: gltf::json::Index<gltf::json::Accessor>| root.accessors.get(i.value());
            let position = primitive
                .attributes
                .get(&Checked::Valid(gltf::json::mesh::Semantic::Positions))
                .and_then(|&i| accessor(i));
            if let Some(a) = position {
                let float_vec3 = matches!(a.type_, Checked::Valid(Type::Vec3))
                    && matches!(&a.component_type, Checked::Valid(c) if c.0 == ComponentType::F32);
                if !float_vec3 {
                    bad.push(format!(
                        "{place}.attributes.POSITION: must be a VEC3 accessor of FLOAT (5126)"
                    ));
                }
            }
            for (semantic, &index) in &primitive.attributes {
                let Checked::Valid(gltf::json::mesh::Semantic::TexCoords(set)) = semantic else {
                    continue;
                };
                let Some(a) = accessor(index) else { continue };
                let ok = matches!(a.type_, Checked::Valid(Type::Vec2))
                    && match &a.component_type {
                        Checked::Valid(c) => {
                            c.0 == ComponentType::F32
                                || (a.normalized
                                    && matches!(c.0, ComponentType::U8 | ComponentType::U16))
                        }
                        _ => false,
                    };
                if !ok {
                    bad.push(format!(
                        "{place}.attributes.TEXCOORD_{set}: must be a VEC2 accessor of FLOAT, or of \
                         normalized UNSIGNED_BYTE or UNSIGNED_SHORT"
                    ));
                }
            }
            if let Some(a) = primitive.indices.and_then(accessor) {
                let unsigned_scalar = matches!(a.type_, Checked::Valid(Type::Scalar))
                    && matches!(&a.component_type, Checked::Valid(c) if matches!(
                        c.0,
                        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                    ));
                if !unsigned_scalar {
                    bad.push(format!(
                        "{place}.indices: must be a SCALAR accessor of UNSIGNED_BYTE, \
                         UNSIGNED_SHORT or UNSIGNED_INT"
                    ));
                }
            }
        }
    }
    for (a, accessor) in root.accessors.iter().enumerate() {
        if accessor.count.0 == 0 || accessor.sparse.as_ref().is_some_and(|s| s.count.0 == 0) {
            bad.push(format!("accessors[{a}]: count must be at least 1"));
        }
        let (Checked::Valid(component), Checked::Valid(kind)) =
            (&accessor.component_type, &accessor.type_)
        else {
            continue;
        };
        let element = component.0.size() * kind.multiplicity();
        let stride = accessor
            .buffer_view
            .and_then(|v| root.buffer_views.get(v.value()))
            .and_then(|v| v.byte_stride);
        if let Some(stride) = stride {
            if stride.0 < element {
                bad.push(format!(
                    "accessors[{a}]: its bufferView's byteStride {} is smaller than one element ({element} bytes)",
                    stride.0
                ));
            }
        }
    }
    if bad.is_empty() {
        return Ok(());
    }
    Err(SceneError::Unreadable(format!(
        "invalid glTF: {}",
        bad.join("; ")
    )))
}

fn load_scene_unchecked(
    bytes: &[u8],
    external: &ExternalFiles,
    max_triangles: usize,
) -> Result<Scene, SceneError> {
    // Parsed without validation first: gltf-json's validation indexes `accessors` with a
    // primitive's POSITION index unchecked (a panic on a bad index, found by fuzzing), so the
    // primitives' accessor indices are checked before it runs.
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| SceneError::Unreadable(e.to_string()))?;
    let root = document.into_json();
    check_version(&root.asset)?;
    check_accessor_indices(&root)?;
    let document =
        gltf::Document::from_json(root).map_err(|e| SceneError::Unreadable(e.to_string()))?;
    let buffers = load_buffers(&document, blob, external)?;
    let mut warnings = Vec::new();
    let mut problems = Vec::new();

    let (textures, texture_of) = read_textures(&document, &buffers, external, &mut problems);
    let translucent = document
        .materials()
        .filter(|m| m.alpha_mode() != gltf::material::AlphaMode::Opaque)
        .count();
    if translucent > 0 {
        warnings.push(format!(
            "{translucent} material(s) use alphaMode MASK or BLEND: alpha is ignored, their surfaces are opaque to light (a decal lying on a wall replaces the wall's colour where it lies)"
        ));
    }
    let materials = read_materials(&document, &texture_of, &mut problems);
    let default_material = materials.len() as u32;
    let mut materials = materials;
    let mut uses_default = false;

    // Nodes to walk: the default scene, else the first scene, else every root node.
    let roots: Vec<gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; document.nodes().len()];
            for n in document.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            document.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };

    let mut triangles = Vec::new();
    let mut texcoords = Vec::new();
    let mut lights = Vec::new();
    let mut cameras: Vec<(usize, gltf::Camera, DMat4)> = Vec::new();
    let mut visited = vec![false; document.nodes().len()];
    let mut stack: Vec<(gltf::Node, DMat4, usize)> =
        roots.into_iter().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    let mut ignored_modes = 0usize;
    let mut instances = Vec::new();
    while let Some((node, parent, depth)) = stack.pop() {
        if visited[node.index()] {
            problems.push(Problem {
                place: format!("node {}", node.index()),
                message: "is reached twice in the node graph (a cycle, or a node with two parents)"
                    .into(),
            });
            continue;
        }
        visited[node.index()] = true;
        if depth > MAX_NODE_DEPTH {
            problems.push(Problem {
                place: format!("node {}", node.index()),
                message: format!("nesting deeper than {MAX_NODE_DEPTH} levels"),
            });
            continue;
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if !world.is_finite() {
            problems.push(Problem {
                place: format!("node {}", node.index()),
                message: "its transform is not finite (NaN or infinity)".into(),
            });
            continue;
        }
        if let Some(mesh) = node.mesh() {
            let before = triangles.len();
            read_mesh(
                &mesh,
                world,
                &buffers,
                &materials,
                default_material,
                &mut uses_default,
                (&mut triangles, &mut texcoords),
                &mut problems,
                &mut ignored_modes,
                max_triangles,
            );
            if triangles.len() > max_triangles {
                return Err(SceneError::Unsolvable(format!(
                    "the scene has more than {max_triangles} triangles (the limit --max-triangles); simplify it or raise the limit"
                )));
            }
            instances.push(MeshInstance {
                node: node.index() as u32,
                mesh: mesh.index() as u32,
                world,
                mirrored: world.determinant() < 0.0,
                triangles: before..triangles.len(),
            });
        }
        if let Some(light) = node.light() {
            match read_light(&light, world) {
                Ok(l) => lights.push(l),
                Err(message) => problems.push(Problem {
                    place: format!("node {} light {}", node.index(), light.index()),
                    message,
                }),
            }
        }
        if let Some(camera) = node.camera() {
            cameras.push((node.index(), camera, world));
        }
        for child in node.children() {
            stack.push((child, world, depth + 1));
        }
    }
    let coloured = document
        .meshes()
        .flat_map(|m| m.primitives())
        .filter(|p| p.get(&gltf::Semantic::Colors(0)).is_some())
        .count();
    if coloured > 0 {
        warnings.push(format!(
            "{coloured} primitive(s) have COLOR_0 vertex colours, which are not read: their reflectance is baseColorFactor x baseColorTexture alone"
        ));
    }
    if ignored_modes > 0 {
        warnings.push(format!(
            "{ignored_modes} primitive(s) of points or lines ignored: only surfaces take part in radiosity"
        ));
    }
    if uses_default {
        materials.push(Material::gltf_default());
    }
    if !problems.is_empty() {
        return Err(SceneError::Invalid(problems));
    }
    if !materials.iter().any(Material::has_texture) {
        texcoords.clear();
    }
    let camera = cameras
        .iter()
        .min_by_key(|c| c.0)
        .and_then(|(node, camera, world)| match read_camera(camera, *world) {
            Ok(c) => Some(c),
            Err(why) => {
                warnings.push(format!(
                    "node {node} camera {}: {why}; the preview frames the scene instead",
                    camera.index()
                ));
                None
            }
        });
    let source = source_json(bytes).map(|json| {
        let images = document
            .images()
            .map(|image| match image.source() {
                gltf::image::Source::View { view, .. } => buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
                    .map(<[u8]>::to_vec),
                gltf::image::Source::Uri { uri, .. } => read_uri(uri, external).ok(),
            })
            .collect();
        std::sync::Arc::new(GltfSource {
            json,
            document,
            buffers,
            images,
            instances,
        })
    });
    let mut scene = Scene::new(triangles, materials, lights, warnings)
        .with_textures(textures, texcoords)
        .with_camera(camera);
    scene.source = source;
    Ok(scene)
}

/// The file's JSON as written (the GLB's JSON chunk, or the whole file), `None` when it does not
/// parse as JSON on its own (the `gltf` crate read it, so this does not happen in practice).
fn source_json(bytes: &[u8]) -> Option<serde_json::Value> {
    let json = if bytes.starts_with(b"glTF") {
        // `check_container` has checked the chunk table.
        let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        bytes.get(20..20usize.checked_add(len)?)?
    } else {
        bytes
    };
    let json = json
        .strip_prefix(b"\xEF\xBB\xBF".as_slice())
        .unwrap_or(json);
    serde_json::from_slice(json).ok()
}

/// The triangles of a primitive as index triples into its vertices, as the importer reads them
/// (strips and fans unrolled, triangle `k` of the result being `TriangleSource::triangle` `k`);
/// `None` for points and lines, or when its indices cannot be read.
pub fn primitive_triangles(
    primitive: &gltf::Primitive,
    buffers: &[Vec<u8>],
    vertex_count: usize,
) -> Option<Vec<[u32; 3]>> {
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
    let indices: Vec<u32> = match primitive.indices() {
        Some(_) => reader.read_indices()?.into_u32().collect(),
        None => (0..vertex_count as u32).collect(),
    };
    triangle_indices(primitive.mode(), &indices)
}

/// Unrolls a primitive's index list into triangles (`None` for points and lines).
fn triangle_indices(mode: gltf::mesh::Mode, indices: &[u32]) -> Option<Vec<[u32; 3]>> {
    use gltf::mesh::Mode;
    Some(match mode {
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|i| {
                if i.is_multiple_of(2) {
                    [indices[i], indices[i + 1], indices[i + 2]]
                } else {
                    [indices[i + 1], indices[i], indices[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..indices.len().saturating_sub(1))
            .map(|i| [indices[0], indices[i], indices[i + 1]])
            .collect(),
        _ => return None,
    })
}

/// A camera node in world space: the node's `-Z` is the view direction, `+Y` the up direction
/// (`camera_node_in_world_space`). Only perspective cameras with a usable field of view and
/// transform; the reason otherwise (the camera only serves the preview: a warning, not a problem).
fn read_camera(camera: &gltf::Camera, world: DMat4) -> Result<Camera, String> {
    let gltf::camera::Projection::Perspective(p) = camera.projection() else {
        return Err("an orthographic camera is not used".into());
    };
    let yfov = f64::from(p.yfov());
    if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
        return Err(format!("yfov {yfov} is not in (0, pi)"));
    }
    let aspect = p.aspect_ratio().map(f64::from);
    if aspect.is_some_and(|a| !(a.is_finite() && a > 0.0)) {
        return Err("aspectRatio is not a positive number".into());
    }
    let znear = f64::from(p.znear());
    let position = world.transform_point3(DVec3::ZERO);
    let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    let up = world.transform_vector3(DVec3::Y);
    // Up made orthogonal to the view direction (a sheared transform may tilt it).
    let up = (up - forward * up.dot(forward)).normalize_or_zero();
    if forward == DVec3::ZERO || up == DVec3::ZERO || !position.is_finite() {
        return Err("its node transform is degenerate (zero scale)".into());
    }
    Ok(Camera {
        position,
        forward,
        up,
        yfov,
        aspect,
        znear: if znear.is_finite() && znear > 0.0 {
            znear
        } else {
            0.0
        },
    })
}

/// glTF's own rule: `asset.version` (and `minVersion`, when given) must be 2.x.
fn check_version(asset: &gltf::json::Asset) -> Result<(), SceneError> {
    let major = |v: &str| {
        v.split('.')
            .next()
            .and_then(|m| m.trim().parse::<u32>().ok())
    };
    if major(&asset.version) != Some(2) {
        return Err(SceneError::Unreadable(format!(
            "asset.version is \"{}\": only glTF 2.x is supported (re-export the file as glTF 2.0)",
            asset.version
        )));
    }
    if let Some(min) = &asset.min_version {
        if major(min) != Some(2) {
            return Err(SceneError::Unreadable(format!(
                "asset.minVersion is \"{min}\": only glTF 2.x is supported"
            )));
        }
    }
    Ok(())
}

fn read_materials(
    document: &gltf::Document,
    texture_of: &[Option<u32>],
    problems: &mut Vec<Problem>,
) -> Vec<Material> {
    document
        .materials()
        .map(|m| {
            let index = m.index().unwrap_or(0);
            let pbr = m.pbr_metallic_roughness();
            let base = pbr.base_color_factor();
            let strength = m.emissive_strength().unwrap_or(1.0) as f64;
            let ef = m.emissive_factor();
            let emission = ef.map(|e| e as f64 * strength);
            let rho = [base[0], base[1], base[2]].map(|c| f64::from(c).clamp(0.0, 1.0));
            if emission.iter().any(|e| !e.is_finite() || *e < 0.0) || base.iter().any(|c| !c.is_finite()) {
                problems.push(Problem {
                    place: format!("material {index}"),
                    message: "baseColorFactor, emissiveFactor or emissiveStrength is not a finite non-negative number".into(),
                });
            }
            Material {
                name: m.name().map(str::to_owned).unwrap_or_else(|| format!("material_{index}")),
                rho,
                emission,
                double_sided: m.double_sided(),
                base_color_texture: pbr
                    .base_color_texture()
                    .and_then(|i| texture_slot(&i, texture_of)),
                emissive_texture: m.emissive_texture().and_then(|i| texture_slot(&i, texture_of)),
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn read_mesh(
    mesh: &gltf::Mesh,
    world: DMat4,
    buffers: &[Vec<u8>],
    materials: &[Material],
    default_material: u32,
    uses_default: &mut bool,
    (triangles, texcoords): (&mut Vec<Triangle>, &mut Vec<TriangleTexcoords>),
    problems: &mut Vec<Problem>,
    ignored_modes: &mut usize,
    max_triangles: usize,
) {
    let mirrored = world.determinant() < 0.0;
    for primitive in mesh.primitives() {
        let place = format!("mesh {} primitive {}", mesh.index(), primitive.index());
        let mode = primitive.mode();
        use gltf::mesh::Mode;
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            *ignored_modes += 1;
            continue;
        }
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let Some(positions) = reader.read_positions() else {
            problems.push(Problem {
                place,
                message: "has no readable POSITION attribute (missing, or its accessor runs past its buffer)".into(),
            });
            continue;
        };
        let positions: Vec<DVec3> = positions
            .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect();
        let indices: Vec<u32> = match primitive.indices() {
            Some(_) => match reader.read_indices() {
                Some(ix) => ix.into_u32().collect(),
                None => {
                    problems.push(Problem {
                        place,
                        message: "its index accessor runs past its buffer".into(),
                    });
                    continue;
                }
            },
            None => (0..positions.len() as u32).collect(),
        };
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            problems.push(Problem {
                place: place.clone(),
                message: format!("{} indices is not a multiple of 3", indices.len()),
            });
        }
        let tri_indices = triangle_indices(mode, &indices).unwrap_or_default();
        if !triangle_problems(&place, &positions, &tri_indices, problems) {
            continue;
        }
        if triangles.len() + tri_indices.len() > max_triangles {
            // The caller reports the limit; don't allocate further.
            triangles.extend(std::iter::repeat_n(
                Triangle {
                    vertices: [DVec3::ZERO; 3],
                    material: 0,
                    source: TriangleSource {
                        mesh: 0,
                        primitive: 0,
                        triangle: 0,
                    },
                },
                max_triangles + 1 - triangles.len(),
            ));
            return;
        }
        let material = match primitive.material().index() {
            Some(i) => i as u32,
            None => {
                *uses_default = true;
                default_material
            }
        };
        let slots = materials
            .get(material as usize)
            .map(|m| [m.base_color_texture, m.emissive_texture])
            .unwrap_or_default();
        let Some(uv_sets) = read_uv_sets(
            &primitive,
            buffers,
            &place,
            slots,
            positions.len(),
            problems,
        ) else {
            continue;
        };
        for (k, idx) in tri_indices.iter().enumerate() {
            let mut v = idx.map(|i| world.transform_point3(positions[i as usize]));
            let mut uv = TriangleTexcoords {
                base_color: idx.map(|i| uv_sets[0].get(i as usize).copied().unwrap_or_default()),
                emissive: idx.map(|i| uv_sets[1].get(i as usize).copied().unwrap_or_default()),
            };
            if mirrored {
                v.swap(1, 2);
                uv.base_color.swap(1, 2);
                uv.emissive.swap(1, 2);
            }
            if v.iter().any(|p| !p.is_finite()) {
                problems.push(Problem {
                    place: triangle_place(&place, k),
                    message: "transformed position is not finite (overflow)".into(),
                });
                continue;
            }
            triangles.push(Triangle {
                vertices: v,
                material,
                source: TriangleSource {
                    mesh: mesh.index() as u32,
                    primitive: primitive.index() as u32,
                    triangle: k as u32,
                },
            });
            texcoords.push(uv);
        }
    }
}

/// At most this many problems are listed per primitive; the rest are counted in one more line.
const MAX_PROBLEMS_PER_PRIMITIVE: usize = 16;

fn triangle_place(primitive_place: &str, triangle: usize) -> String {
    format!("{primitive_place} triangle {triangle}")
}

/// Checks every triangle of a primitive: its indices in range and its vertices finite. Each bad
/// triangle is one [`Problem`] at "mesh M primitive P triangle K" (up to
/// [`MAX_PROBLEMS_PER_PRIMITIVE`], then a count). Returns whether the primitive is clean. Vertices no
/// triangle uses are not checked: they cannot reach the solver.
fn triangle_problems(
    place: &str,
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    problems: &mut Vec<Problem>,
) -> bool {
    let n = positions.len();
    let mut bad = 0usize;
    for (k, tri) in triangles.iter().enumerate() {
        let message = if let Some(&ix) = tri.iter().find(|&&ix| ix as usize >= n) {
            format!("index {ix} is out of range: the primitive has {n} vertices")
        } else if let Some(&ix) = tri.iter().find(|&&ix| !positions[ix as usize].is_finite()) {
            format!("vertex {ix} has a NaN or infinite position")
        } else {
            continue;
        };
        bad += 1;
        if bad <= MAX_PROBLEMS_PER_PRIMITIVE {
            problems.push(Problem {
                place: triangle_place(place, k),
                message,
            });
        }
    }
    if bad > MAX_PROBLEMS_PER_PRIMITIVE {
        problems.push(Problem {
            place: place.to_owned(),
            message: format!(
                "{} more triangle(s) with out-of-range indices or NaN/infinite positions",
                bad - MAX_PROBLEMS_PER_PRIMITIVE
            ),
        });
    }
    bad == 0
}

fn read_light(
    light: &gltf::khr_lights_punctual::Light,
    world: DMat4,
) -> Result<PunctualLight, String> {
    use gltf::khr_lights_punctual::Kind;
    let c = light.color();
    let i = light.intensity() as f64;
    let intensity = [c[0] as f64 * i, c[1] as f64 * i, c[2] as f64 * i];
    if intensity.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err("colour * intensity is not a finite non-negative number".into());
    }
    let position = world.transform_point3(DVec3::ZERO);
    // Lights point along their local -Z.
    let direction = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    if direction == DVec3::ZERO && !matches!(light.kind(), Kind::Point) {
        return Err("its node transform collapses the light's direction".into());
    }
    let kind = match light.kind() {
        Kind::Point => LightKind::Point { position },
        Kind::Directional => LightKind::Directional { direction },
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => LightKind::Spot {
            position,
            direction,
            inner_cone_angle: inner_cone_angle as f64,
            outer_cone_angle: outer_cone_angle as f64,
        },
    };
    Ok(PunctualLight {
        name: light.name().unwrap_or("light").to_owned(),
        kind,
        intensity,
    })
}

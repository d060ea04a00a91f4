//! Buffer loading for glTF: the GLB binary chunk, data URIs, and external files resolved by the
//! caller's [`ExternalFiles`] policy. Replaces the `gltf` crate's `import` feature (which pulls in
//! image decoding) and never touches disk or network unless the policy allows it.
//!
//! Invariant: a returned buffer is at least as long as its declared `byteLength` (truncated data is
//! refused here, so accessor reads past this point cannot run off the end of real data).

use super::error::{Problem, SceneError};
use base64::Engine;
use std::collections::HashMap;
use std::path::PathBuf;

/// How URIs that are not data URIs are resolved.
#[derive(Debug, Clone, Default)]
pub enum ExternalFiles {
    /// Refuse every external URI (the HTTP default: never resolve against the server's disk).
    #[default]
    Refuse,
    /// Resolve relative to this directory (the CLI, next to the `.gltf` file).
    Directory(PathBuf),
    /// Resolve by name among these files (a multipart upload).
    Named(HashMap<String, Vec<u8>>),
}

/// Largest buffer a data URI or external file may declare (bytes); bigger is refused before
/// allocation so a lying `byteLength` cannot exhaust memory.
pub const MAX_BUFFER_BYTES: u64 = 2 << 30;

pub(crate) fn load_buffers(
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    external: &ExternalFiles,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut buffers = Vec::new();
    let mut problems = Vec::new();
    for buffer in document.buffers() {
        let place = format!("buffer {}", buffer.index());
        let declared = buffer.length() as u64;
        if declared > MAX_BUFFER_BYTES {
            problems.push(Problem {
                place,
                message: format!(
                    "declares {declared} bytes, more than the limit of {MAX_BUFFER_BYTES}"
                ),
            });
            buffers.push(Vec::new());
            continue;
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => match blob.take() {
                Some(b) => Ok(b),
                None => Err("refers to the GLB binary chunk, but the file has none".to_string()),
            },
            gltf::buffer::Source::Uri(uri) => read_uri(uri, external),
        };
        match data {
            Ok(d) if (d.len() as u64) < declared => {
                problems.push(Problem {
                    place,
                    message: format!(
                        "declares {declared} bytes but holds only {} (truncated file or lying byteLength)",
                        d.len()
                    ),
                });
                buffers.push(Vec::new());
            }
            Ok(mut d) => {
                // The buffer is `byteLength` bytes: bytes past it (GLB chunk padding, a data URI
                // longer than declared) are not part of it, so views cannot reach them.
                d.truncate(declared as usize);
                buffers.push(d)
            }
            Err(message) => {
                problems.push(Problem { place, message });
                buffers.push(Vec::new());
            }
        }
    }
    if problems.is_empty() {
        Ok(buffers)
    } else {
        Err(SceneError::Invalid(problems))
    }
}

pub(crate) fn read_uri(uri: &str, external: &ExternalFiles) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((header, payload)) = rest.split_once(',') else {
            return Err("data URI has no ',' separating header and payload".into());
        };
        if !header.ends_with(";base64") {
            return Err(
                "data URI is not base64-encoded (only ';base64' data URIs are supported)".into(),
            );
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| format!("data URI is not valid base64: {e}"));
    }
    let name = percent_encoding::percent_decode_str(uri)
        .decode_utf8()
        .map_err(|_| format!("URI '{uri}' is not valid UTF-8 after percent-decoding"))?
        .into_owned();
    match external {
        ExternalFiles::Refuse => Err(format!(
            "external URI '{uri}' is not allowed here: embed buffers as data URIs, send a GLB, or upload the file as a multipart part named '{uri}'"
        )),
        ExternalFiles::Named(files) => files
            .get(&name)
            .or_else(|| files.get(uri))
            .cloned()
            .ok_or_else(|| format!("external URI '{uri}' names no part of the upload")),
        ExternalFiles::Directory(dir) => {
            if name.contains("..") || name.starts_with('/') || name.contains(':') {
                return Err(format!(
                    "external URI '{uri}' must be a relative path inside the scene's folder"
                ));
            }
            let path = dir.join(&name);
            let meta = std::fs::metadata(&path)
                .map_err(|e| format!("cannot read '{}': {e}", path.display()))?;
            if meta.len() > MAX_BUFFER_BYTES {
                return Err(format!("'{}' is larger than {MAX_BUFFER_BYTES} bytes", path.display()));
            }
            std::fs::read(&path).map_err(|e| format!("cannot read '{}': {e}", path.display()))
        }
    }
}

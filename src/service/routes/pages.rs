//! The 3-D view page (`GET /view?job=ID`) and the static files pages load (`GET /assets/{file}`):
//! the view's script and three.js, vendored (`assets/three/README.md` says which files and
//! version), all embedded in the binary at build time so no page needs a CDN.
//!
//! Invariant: only the files of [`ASSETS`] are served, by exact name (no path is resolved on
//! disk); every answer carries a content security policy that allows this server only.

use super::super::error::ApiError;
use super::super::extract::ApiPath;
use axum::body::Body;
use axum::http::{header, HeaderValue};
use axum::response::Response;

/// Pages of the service may load scripts, images and data from this server only (`blob:` for
/// the images a glTF embeds, which the loader decodes through object URLs).
pub const PAGE_CSP: &str = "default-src 'none'; script-src 'self' 'unsafe-inline'; \
     style-src 'unsafe-inline'; connect-src 'self' blob: data:; img-src 'self' blob: data:";

/// Every file under `/assets/`: name, content type, bytes.
const ASSETS: &[(&str, &str, &[u8])] = &[
    (
        "viewer.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/viewer.js"),
    ),
    (
        "three/three.module.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/three.module.js"),
    ),
    (
        "three/three.core.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/three.core.js"),
    ),
    (
        "three/addons/loaders/GLTFLoader.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/addons/loaders/GLTFLoader.js"),
    ),
    (
        "three/addons/controls/OrbitControls.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/addons/controls/OrbitControls.js"),
    ),
    (
        "three/addons/utils/BufferGeometryUtils.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/addons/utils/BufferGeometryUtils.js"),
    ),
    (
        "three/addons/utils/SkeletonUtils.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../assets/three/addons/utils/SkeletonUtils.js"),
    ),
    (
        "three/LICENSE",
        "text/plain; charset=utf-8",
        include_bytes!("../assets/three/LICENSE"),
    ),
];

/// The 3-D view page, embedded at build time.
const VIEWER_HTML: &str = include_str!("../assets/viewer.html");

fn page_response(body: Body, content_type: &'static str) -> Response {
    let mut response = Response::new(body);
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(PAGE_CSP),
    );
    response
}

/// `GET /view?job=ID`: the 3-D view of a finished bake (its script reads the job from the query
/// and fetches `scene.glb` with the dashboard's token).
pub async fn viewer() -> Response {
    page_response(Body::from(VIEWER_HTML), "text/html; charset=utf-8")
}

/// `GET /assets/{file}`: one of [`ASSETS`], cached by the browser for an hour.
pub async fn asset(ApiPath(file): ApiPath<String>) -> Result<Response, ApiError> {
    let Some((_, content_type, bytes)) = ASSETS.iter().find(|(name, _, _)| *name == file) else {
        return Err(ApiError::file_not_found(format!(
            "no asset '{file}': the service serves only its own page scripts and three.js"
        )));
    };
    let mut response = page_response(Body::from(*bytes), content_type);
    response.headers_mut().insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static("public, max-age=3600"),
    );
    Ok(response)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_import_of_a_vendored_file_is_served() {
        // The view's import map sends `three` to three.module.js and `three/addons/` to the
        // addons; relative imports between vendored files must name served files too.
        for (name, _, bytes) in ASSETS {
            let Ok(text) = std::str::from_utf8(bytes) else {
                continue;
            };
            let dir = name.rsplit_once('/').map(|(d, _)| d).unwrap_or("");
            for line in text.lines().filter(|l| l.contains("from '")) {
                let target = line
                    .split("from '")
                    .nth(1)
                    .and_then(|s| s.split('\'').next());
                let Some(target) = target else { continue };
                let resolved = if target == "three" {
                    "three/three.module.js".to_string()
                } else if let Some(rest) = target.strip_prefix("three/addons/") {
                    format!("three/addons/{rest}")
                } else if let Some(rest) = target.strip_prefix("./") {
                    format!("{dir}/{rest}")
                } else if let Some(rest) = target.strip_prefix("../") {
                    let parent = dir.rsplit_once('/').map(|(d, _)| d).unwrap_or("");
                    format!("{parent}/{rest}")
                } else {
                    continue;
                };
                assert!(
                    ASSETS.iter().any(|(n, _, _)| *n == resolved),
                    "{name} imports {target} ({resolved}), which is not served"
                );
            }
        }
    }
}

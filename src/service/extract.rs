//! Extractors that wrap axum's and turn their rejections into [`ApiError`], so a request refused
//! before any handler runs still gets the error JSON of docs/contract.md. (The query of
//! `POST /v1/jobs` is parsed by `routes::submit`, which takes the scene's `name` out of it.)

use super::error::ApiError;
use axum::extract::{FromRequestParts, Path};
use axum::http::request::Parts;
use serde::de::DeserializeOwned;

/// `Path<T>` whose rejection is an error JSON with the rejection's status (400, or 500 for a
/// routing mistake of ours).
#[derive(Debug, Clone)]
pub struct ApiPath<T>(pub T);

impl<T, S> FromRequestParts<S> for ApiPath<T>
where
    T: DeserializeOwned + Send,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Self::Rejection> {
        match Path::<T>::from_request_parts(parts, state).await {
            Ok(Path(value)) => Ok(ApiPath(value)),
            Err(rejection) => {
                let status = rejection.status();
                if status.is_server_error() {
                    Err(ApiError::internal(
                        "the route's path parameters do not match its handler",
                        rejection.body_text(),
                    ))
                } else {
                    Err(ApiError::new(status, "bad_path", rejection.body_text()))
                }
            }
        }
    }
}

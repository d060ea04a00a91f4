//! Extractors that wrap axum's and turn their rejections into [`ApiError`], so a request refused
//! before any handler runs still gets the error JSON of docs/contract.md.

use super::error::ApiError;
use axum::extract::{FromRequestParts, Path, Query};
use axum::http::request::Parts;
use serde::de::DeserializeOwned;

/// `Query<T>` whose rejection is a 400 `bad_parameters` naming what is wrong.
#[derive(Debug, Clone)]
pub struct ApiQuery<T>(pub T);

impl<T, S> FromRequestParts<S> for ApiQuery<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Self::Rejection> {
        match Query::<T>::from_request_parts(parts, state).await {
            Ok(Query(value)) => Ok(ApiQuery(value)),
            Err(rejection) => Err(ApiError::bad_parameters(format!(
                "{}; parameters and their ranges are listed in api/openapi.yaml",
                rejection.body_text()
            ))),
        }
    }
}

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

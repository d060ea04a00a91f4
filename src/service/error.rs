//! The one HTTP error type, rendered as the error JSON of docs/contract.md
//! `{"error": {"code": "snake_case", "message": "..."}}`, and the safety nets that give every other
//! failure (panics, timeouts, middleware rejections) the same shape.

use crate::scene::SceneError;
use axum::body::Body;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use std::any::Any;
use std::borrow::Cow;

/// Largest error body of another layer read back to reuse its text as the message.
const MAX_FOREIGN_ERROR_BODY: usize = 16 * 1024;

/// An error answer: status, stable snake_case code, and a message that says what is wrong and what
/// to do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiError {
    pub status: StatusCode,
    pub code: Cow<'static, str>,
    pub message: String,
    /// Seconds for a `Retry-After` header (429, 503).
    pub retry_after: Option<u64>,
}

/// The `{"code", "message"}` object, inside the error document and in a failed job's `error`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct ErrorBody {
    pub code: String,
    pub message: String,
}

#[derive(Serialize)]
struct ErrorDocument<'a> {
    error: ErrorRef<'a>,
}

#[derive(Serialize)]
struct ErrorRef<'a> {
    code: &'a str,
    message: &'a str,
}

impl ApiError {
    pub fn new(
        status: StatusCode,
        code: impl Into<Cow<'static, str>>,
        message: impl Into<String>,
    ) -> Self {
        ApiError {
            status,
            code: code.into(),
            message: message.into(),
            retry_after: None,
        }
    }

    /// 400 for a request whose parameters are wrong.
    pub fn bad_parameters(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "bad_parameters", message)
    }

    /// 404 for a job id that does not exist (or no longer does).
    pub fn job_not_found(id: &str) -> Self {
        Self::new(
            StatusCode::NOT_FOUND,
            "job_not_found",
            format!(
                "no job with id '{}'; GET /v1/jobs lists the jobs this server knows",
                clip(id, 80)
            ),
        )
    }

    /// 404 for a file of a job that does not exist.
    pub fn file_not_found(message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "file_not_found", message)
    }

    /// 409: the job is not in a state where this is available.
    pub fn conflict(code: &'static str, message: impl Into<String>) -> Self {
        Self::new(StatusCode::CONFLICT, code, message)
    }

    /// 422 for an `Idempotency-Key` already used by a request with another body or other
    /// parameters (a retry must repeat the request exactly; a new job needs a new key).
    pub fn idempotency_key_reused(key: &str) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "idempotency_key_reused",
            format!(
                "the Idempotency-Key '{}' was already used for a different request (another body \
                 or other parameters); a retry must send the same request, a new job needs a new key",
                clip(key, 80)
            ),
        )
    }

    /// 429 with `Retry-After`.
    pub fn queue_full(max_queued: usize, retry_after: u64) -> Self {
        ApiError {
            retry_after: Some(retry_after),
            ..Self::new(
                StatusCode::TOO_MANY_REQUESTS,
                "queue_full",
                format!(
                    "the job queue is full ({max_queued} job(s) waiting); retry after {retry_after} s"
                ),
            )
        }
    }

    /// 500. The detail goes to the log; the client gets `context` and a pointer to the log.
    pub fn internal(context: &str, detail: impl std::fmt::Display) -> Self {
        tracing::error!(%detail, "{context}");
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal_error",
            format!("{context}; the server log has the details"),
        )
    }

    /// The error for `status` when nothing more specific is known.
    pub fn from_status(status: StatusCode, message: Option<String>) -> Self {
        let code = match status {
            StatusCode::BAD_REQUEST => "bad_request",
            StatusCode::UNAUTHORIZED => "unauthorized",
            StatusCode::FORBIDDEN => "forbidden",
            StatusCode::NOT_FOUND => "not_found",
            StatusCode::METHOD_NOT_ALLOWED => "method_not_allowed",
            StatusCode::REQUEST_TIMEOUT => "request_timeout",
            StatusCode::CONFLICT => "conflict",
            StatusCode::PAYLOAD_TOO_LARGE => "payload_too_large",
            StatusCode::UNSUPPORTED_MEDIA_TYPE => "unsupported_media_type",
            StatusCode::UNPROCESSABLE_ENTITY => "unprocessable",
            StatusCode::TOO_MANY_REQUESTS => "too_many_requests",
            StatusCode::SERVICE_UNAVAILABLE => "unavailable",
            s if s.is_client_error() => "client_error",
            _ => "internal_error",
        };
        let message = message
            .filter(|m| !m.trim().is_empty())
            .unwrap_or_else(|| status.canonical_reason().unwrap_or("error").to_string());
        Self::new(status, code, message)
    }

    /// The error document as JSON bytes.
    pub fn to_json(&self) -> Vec<u8> {
        let doc = ErrorDocument {
            error: ErrorRef {
                code: &self.code,
                message: &self.message,
            },
        };
        // Serialising two strings cannot fail; the fallback keeps the shape anyway.
        serde_json::to_vec(&doc).unwrap_or_else(|_| {
            br#"{"error":{"code":"internal_error","message":"error"}}"#.to_vec()
        })
    }

    pub fn body(&self) -> ErrorBody {
        ErrorBody {
            code: self.code.to_string(),
            message: self.message.clone(),
        }
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {}: {}",
            self.status.as_u16(),
            self.code,
            self.message
        )
    }
}

impl std::error::Error for ApiError {}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response = Response::new(Body::from(self.to_json()));
        *response.status_mut() = self.status;
        let headers = response.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        );
        if let Some(seconds) = self.retry_after {
            headers.insert(header::RETRY_AFTER, HeaderValue::from(seconds));
        }
        response
    }
}

/// A scene that cannot be solved is the client's to fix: 422 with the importer's code and reason.
impl From<SceneError> for ApiError {
    fn from(e: SceneError) -> Self {
        ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, e.code(), e.to_string())
    }
}

/// At most `n` characters of `s` (for echoing client input in messages).
pub(crate) fn clip(s: &str, n: usize) -> String {
    match s.char_indices().nth(n) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

/// Router fallback: unknown routes.
pub async fn route_not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        "not_found",
        format!(
            "no route for '{}'; the API lives under /v1 (see api/openapi.yaml)",
            clip(uri.path(), 200)
        ),
    )
}

/// Router fallback: a known path with a method it does not have.
pub async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        format!(
            "{method} is not allowed on '{}' (see api/openapi.yaml)",
            clip(uri.path(), 200)
        ),
    )
}

/// `CatchPanicLayer` handler: a handler that panicked answers 500 in the error shape.
pub fn panic_response(payload: Box<dyn Any + Send + 'static>) -> Response<Body> {
    let detail = panic_message(payload.as_ref());
    ApiError::internal("the request handler failed", detail).into_response()
}

/// The text of a panic payload.
pub fn panic_message(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-text payload".to_string()
    }
}

/// Last line: an error response made by another layer (a timeout, a limit, an extractor we did not
/// wrap) without a JSON body is rewritten into the error JSON, keeping its status and its text.
pub async fn normalize_error_response(response: Response) -> Response {
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if is_json {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, MAX_FOREIGN_ERROR_BODY)
        .await
        .ok()
        .and_then(|b| String::from_utf8(b.to_vec()).ok());
    let mut error = ApiError::from_status(status, text);
    if let Some(seconds) = parts
        .headers
        .get(header::RETRY_AFTER)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse().ok())
    {
        error.retry_after = Some(seconds);
    }
    let mut out = error.into_response();
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            out.headers_mut().insert(name.clone(), value.clone());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_json_shape() {
        let e = ApiError::bad_parameters("order must be 1, 2 or 3 (got 7)");
        let v: serde_json::Value = serde_json::from_slice(&e.to_json()).unwrap();
        assert_eq!(v["error"]["code"], "bad_parameters");
        assert_eq!(v["error"]["message"], "order must be 1, 2 or 3 (got 7)");
    }

    #[test]
    fn clip_keeps_char_boundaries() {
        assert_eq!(clip("abc", 5), "abc");
        assert_eq!(clip("ééééé", 2), "éé...");
    }

    #[test]
    fn status_fallback_has_a_message() {
        let e = ApiError::from_status(StatusCode::REQUEST_TIMEOUT, Some("  ".into()));
        assert_eq!(e.code, "request_timeout");
        assert_eq!(e.message, "Request Timeout");
    }
}

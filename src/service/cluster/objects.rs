//! The object store of cluster mode (`--object-store`): `s3://BUCKET[/prefix]`, configured from
//! the environment as `object_store`'s `AmazonS3Builder::from_env` reads it (`AWS_ENDPOINT_URL`,
//! `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_REGION`, `AWS_ALLOW_HTTP`), or
//! `file:///path`.
//!
//! Layout under the prefix, one folder per job: `jobs/{id}/input.glb|input.gltf` and
//! `jobs/{id}/part-{n}` (the upload, written before the 202), `jobs/{id}/attempt-{n}/{file}` (the
//! outputs of attempt n, written before the row says it finished; only the attempt the row names
//! is ever read, so a fenced-out attempt's files are never served).

use bytes::Bytes;
use futures_util::StreamExt;
use object_store::path::Path;
use object_store::{ObjectStore, ObjectStoreExt, PutPayload};
use std::io;
use std::sync::Arc;

/// A parsed `--object-store` URL.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StoreUrl {
    S3 { bucket: String, prefix: String },
    File { root: std::path::PathBuf },
}

/// Parses `s3://BUCKET[/prefix]` or `file:///absolute/path`; the error says what is accepted.
pub fn parse_url(url: &str) -> Result<StoreUrl, String> {
    if let Some(rest) = url.strip_prefix("s3://") {
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(format!(
                "--object-store '{url}' names no bucket (s3://BUCKET[/prefix])"
            ));
        }
        return Ok(StoreUrl::S3 {
            bucket: bucket.to_string(),
            prefix: prefix.trim_matches('/').to_string(),
        });
    }
    if let Some(path) = url.strip_prefix("file://") {
        if !path.starts_with('/') {
            return Err(format!(
                "--object-store '{url}': a file URL needs an absolute path (file:///path)"
            ));
        }
        return Ok(StoreUrl::File { root: path.into() });
    }
    Err(format!(
        "--object-store '{url}' is not understood: use s3://BUCKET[/prefix] (endpoint and \
         credentials from AWS_* variables) or file:///path"
    ))
}

/// The object store with its prefix.
#[derive(Debug, Clone)]
pub struct Objects {
    store: Arc<dyn ObjectStore>,
    prefix: String,
}

impl Objects {
    pub fn open(url: &str) -> io::Result<Objects> {
        let invalid = |e: String| io::Error::new(io::ErrorKind::InvalidInput, e);
        match parse_url(url).map_err(invalid)? {
            StoreUrl::S3 { bucket, prefix } => {
                let store = object_store::aws::AmazonS3Builder::from_env()
                    .with_bucket_name(bucket)
                    .build()
                    .map_err(|e| invalid(format!("--object-store: {e}")))?;
                Ok(Objects {
                    store: Arc::new(store),
                    prefix,
                })
            }
            StoreUrl::File { root } => {
                std::fs::create_dir_all(&root)?;
                let store = object_store::local::LocalFileSystem::new_with_prefix(&root)
                    .map_err(|e| invalid(format!("--object-store: {e}")))?;
                Ok(Objects {
                    store: Arc::new(store),
                    prefix: String::new(),
                })
            }
        }
    }

    fn path(&self, key: &str) -> Path {
        if self.prefix.is_empty() {
            Path::from(key)
        } else {
            Path::from(format!("{}/{key}", self.prefix))
        }
    }

    /// The key of a job's object `name` (`input.glb`, `part-0`, ...).
    pub fn job_key(id: &str, name: &str) -> String {
        format!("jobs/{id}/{name}")
    }

    /// The key of an output of attempt `attempt`.
    pub fn output_key(id: &str, attempt: i32, name: &str) -> String {
        format!("jobs/{id}/attempt-{attempt}/{name}")
    }

    pub async fn put(&self, key: &str, bytes: Bytes) -> io::Result<()> {
        self.store
            .put(&self.path(key), PutPayload::from_bytes(bytes))
            .await
            .map(|_| ())
            .map_err(|e| io::Error::other(format!("object store: writing {key}: {e}")))
    }

    /// The object, or None when it does not exist.
    pub async fn get(&self, key: &str) -> io::Result<Option<Bytes>> {
        let read = async { self.store.get(&self.path(key)).await?.bytes().await };
        match read.await {
            Ok(bytes) => Ok(Some(bytes)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(io::Error::other(format!(
                "object store: reading {key}: {e}"
            ))),
        }
    }

    /// Deletes every object under `jobs/{id}/`.
    pub async fn delete_job(&self, id: &str) -> io::Result<()> {
        let prefix = self.path(&format!("jobs/{id}"));
        let mut listing = self.store.list(Some(&prefix));
        let mut paths = Vec::new();
        while let Some(meta) = listing.next().await {
            let meta = meta.map_err(|e| io::Error::other(format!("object store: listing: {e}")))?;
            paths.push(meta.location);
        }
        for path in paths {
            match self.store.delete(&path).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
                Err(e) => return Err(io::Error::other(format!("object store: deleting: {e}"))),
            }
        }
        Ok(())
    }

    /// Deletes the outputs of one attempt (a fenced-out attempt's uploads).
    pub async fn delete_attempt(&self, id: &str, attempt: i32) -> io::Result<()> {
        let prefix = self.path(&format!("jobs/{id}/attempt-{attempt}"));
        let mut listing = self.store.list(Some(&prefix));
        while let Some(meta) = listing.next().await {
            let Ok(meta) = meta else { break };
            let _ = self.store.delete(&meta.location).await;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn object_store_urls() {
        assert_eq!(
            parse_url("s3://bake/prod/a").unwrap(),
            StoreUrl::S3 {
                bucket: "bake".into(),
                prefix: "prod/a".into()
            }
        );
        assert_eq!(
            parse_url("s3://bake").unwrap(),
            StoreUrl::S3 {
                bucket: "bake".into(),
                prefix: String::new()
            }
        );
        assert!(parse_url("s3://").is_err());
        assert!(parse_url("file://rel").is_err());
        assert!(parse_url("http://x").unwrap_err().contains("s3://BUCKET"));
        assert_eq!(
            parse_url("file:///tmp/x").unwrap(),
            StoreUrl::File {
                root: "/tmp/x".into()
            }
        );
    }
}

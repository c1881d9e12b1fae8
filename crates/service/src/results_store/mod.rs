//! Where job results live: a folder shared by the API and every worker (the default), or an
//! S3-compatible bucket (`--store s3://bucket/prefix`).
//!
//! Either way a job's process writes its Zarr store into a local folder
//! ([`ResultsStore::results_dir`]): the shared folder itself, or with S3 the worker's own
//! scratch folder, which [`JobSync`] mirrors to the objects `prefix/<id>/results.zarr/<key>`
//! (a Zarr v3 store's keys are its relative file paths, so that prefix is itself a Zarr store).
//! The mirror is made before a run (an earlier attempt's store comes down, so the run resumes
//! from its checkpoint on any machine), after each new checkpoint, and when the run ends. The
//! API reads, lists and draws from here without knowing which kind it is.

mod local;
mod s3;

use std::path::{Path, PathBuf};

/// A job's store folder inside its job folder.
pub(crate) const RESULTS: &str = "results.zarr";

/// The folder name, in a job's folder, of the stored state it starts from (S3 stores).
const START: &str = "start.zarr";

/// Where the result stores are, as given to `--store`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StoreLocation {
    /// A folder of `<id>/results.zarr` stores (shared by every machine: NFS or one machine).
    Folder(PathBuf),
    /// The objects `<prefix>/<id>/results.zarr/<key>` of an S3 bucket; endpoint, region and
    /// credentials come from the AWS environment variables.
    S3 {
        /// The bucket's name.
        bucket: String,
        /// The key prefix, without leading or trailing `/` (may be empty).
        prefix: String,
    },
}

impl StoreLocation {
    /// Reads `--store`: `s3://bucket/prefix` or a folder. Any other `scheme://`, an empty or
    /// malformed bucket name, or a prefix with empty, `.` or `..` segments is an error.
    pub fn parse(text: &str) -> Result<Self, StoreError> {
        let bad = |reason: &str| StoreError::BadLocation {
            location: text.to_string(),
            reason: reason.to_string(),
        };
        let Some(rest) = text.strip_prefix("s3://") else {
            if let Some((scheme, _)) = text.split_once("://") {
                return Err(bad(&format!(
                    "`{scheme}://` is not supported; give a folder or s3://BUCKET/PREFIX"
                )));
            }
            if text.is_empty() {
                return Err(bad("the folder is empty"));
            }
            return Ok(Self::Folder(PathBuf::from(text)));
        };
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(bad("no bucket name (s3://BUCKET/PREFIX)"));
        }
        let valid_bucket = (3..=63).contains(&bucket.len())
            && bucket
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'.' || b == b'-')
            && bucket.starts_with(|c: char| c.is_ascii_alphanumeric())
            && bucket.ends_with(|c: char| c.is_ascii_alphanumeric());
        if !valid_bucket {
            return Err(bad(&format!(
                "`{bucket}` is not a bucket name (3 to 63 of a-z, 0-9, `.`, `-`, starting and \
                 ending with a letter or digit)"
            )));
        }
        let prefix = prefix.trim_end_matches('/');
        if !prefix.is_empty()
            && prefix
                .split('/')
                .any(|s| s.is_empty() || s == "." || s == ".." || s.contains(['\\', '\0']))
        {
            return Err(bad(&format!(
                "the prefix `{prefix}` has an empty, `.` or `..` segment"
            )));
        }
        Ok(Self::S3 {
            bucket: bucket.to_string(),
            prefix: prefix.to_string(),
        })
    }
}

impl std::fmt::Display for StoreLocation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Folder(p) => write!(f, "{}", p.display()),
            Self::S3 { bucket, prefix } if prefix.is_empty() => write!(f, "s3://{bucket}"),
            Self::S3 { bucket, prefix } => write!(f, "s3://{bucket}/{prefix}"),
        }
    }
}

/// Failures of the result store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// `--store` is neither a folder nor a well-formed `s3://bucket/prefix`.
    #[error("`{location}` is not a result store: {reason}")]
    BadLocation {
        /// What was given.
        location: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The bucket does not exist on the server (or these credentials may not see it).
    #[error("bucket `{bucket}` not found at {endpoint}: {message}")]
    NoBucket {
        /// The bucket's name.
        bucket: String,
        /// The server asked (`AWS_ENDPOINT_URL`, or AWS's).
        endpoint: String,
        /// The server's answer.
        message: String,
    },
    /// A local file or folder could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file or folder.
        path: String,
        /// The underlying error.
        error: std::io::Error,
    },
    /// The object store refused or failed a request (its message holds the request and the
    /// server's answer).
    #[error("object store: {0}")]
    Object(object_store::Error),
}

impl From<object_store::Error> for StoreError {
    fn from(e: object_store::Error) -> Self {
        Self::Object(e)
    }
}

impl StoreError {
    /// Whether the error is in what was given (a malformed location, a bucket the server
    /// does not have) rather than in the machine or the network: `mpm` exits 2 for it.
    pub fn is_input(&self) -> bool {
        matches!(self, Self::BadLocation { .. } | Self::NoBucket { .. })
    }

    /// An I/O error at `path`.
    fn io(path: &Path, error: std::io::Error) -> Self {
        Self::Io {
            path: path.display().to_string(),
            error,
        }
    }
}

/// The result stores of a running service (API or worker).
#[derive(Debug)]
pub(crate) enum ResultsStore {
    /// Stores in a shared folder, written and read in place.
    Local(local::LocalStore),
    /// Stores in an S3 bucket, written in a scratch folder and mirrored.
    S3(s3::S3Store),
}

/// A store made readable as a local folder (for drawing pictures), removed when dropped if
/// it was a temporary copy.
pub(crate) struct LocalCopy {
    /// The store folder.
    pub path: PathBuf,
    /// Keeps a temporary copy alive.
    _temp: Option<tempfile::TempDir>,
}

impl ResultsStore {
    /// Opens the stores at `location`; for S3, checks the bucket answers and makes the
    /// scratch folder where jobs write before their results are uploaded.
    pub async fn open(location: &StoreLocation, scratch: &Path) -> Result<Self, StoreError> {
        match location {
            StoreLocation::Folder(root) => Ok(Self::Local(local::LocalStore::open(root)?)),
            StoreLocation::S3 { bucket, prefix } => {
                Ok(Self::S3(s3::S3Store::open(bucket, prefix, scratch).await?))
            }
        }
    }

    /// The folder a job's process works in (`scene.json`, `results.zarr`).
    pub fn job_dir(&self, id: &str) -> PathBuf {
        match self {
            Self::Local(s) => s.root.join(id),
            Self::S3(s) => s.scratch.join(id),
        }
    }

    /// The local folder a job's process writes its store into.
    pub fn results_dir(&self, id: &str) -> PathBuf {
        self.job_dir(id).join(RESULTS)
    }

    /// The bytes of `key` (a relative path checked by the caller) of a job's store; `None`
    /// when there is no such file or object.
    pub async fn read(&self, id: &str, key: &str) -> Result<Option<Vec<u8>>, StoreError> {
        match self {
            Self::Local(s) => s.read(&self.results_dir(id), key).await,
            Self::S3(s) => s.read(id, key).await,
        }
    }

    /// Every key of a job's store, sorted; empty when it has none yet.
    pub async fn list(&self, id: &str) -> Result<Vec<String>, StoreError> {
        match self {
            Self::Local(_) => local::list_files(self.results_dir(id)).await,
            Self::S3(s) => s.list(id).await,
        }
    }

    /// Whether a job has a store yet (its root `zarr.json`).
    pub async fn has_results(&self, id: &str) -> Result<bool, StoreError> {
        match self {
            Self::Local(_) => Ok(
                tokio::fs::try_exists(self.results_dir(id).join("zarr.json"))
                    .await
                    .unwrap_or(false),
            ),
            Self::S3(s) => s.exists(id, "zarr.json").await,
        }
    }

    /// A job's store as a local folder for reading: in place for a folder; for S3 a copy
    /// without the checkpoints, kept for a job that has ended (`ended`), else temporary.
    pub async fn local_copy(&self, id: &str, ended: bool) -> Result<LocalCopy, StoreError> {
        match self {
            Self::Local(_) => Ok(LocalCopy {
                path: self.results_dir(id),
                _temp: None,
            }),
            Self::S3(s) => {
                let (path, temp) = s.local_copy(id, ended).await?;
                Ok(LocalCopy { path, _temp: temp })
            }
        }
    }

    /// The group `group` of job `source`'s store as a local store for job `id` to start
    /// from: the source's own folder for a folder of stores; for S3, its root `zarr.json` and
    /// that group downloaded into `id`'s folder (`start.zarr`, removed with it).
    pub async fn start_state(
        &self,
        id: &str,
        source: &str,
        group: &str,
    ) -> Result<PathBuf, StoreError> {
        match self {
            Self::Local(_) => Ok(self.results_dir(source)),
            Self::S3(s) => {
                let dir = self.job_dir(id).join(START);
                s.fetch_group(source, group, &dir).await?;
                Ok(dir)
            }
        }
    }

    /// Gets a job's folder ready for its `attempt`th run and returns what keeps its store in
    /// step: with S3, the store an earlier attempt uploaded comes down into the scratch folder
    /// (the run resumes from its checkpoint), replacing what was there.
    pub async fn prepare(&self, id: &str, attempt: i64) -> Result<JobSync, StoreError> {
        match self {
            Self::Local(_) => Ok(JobSync(None)),
            Self::S3(s) => Ok(JobSync(Some(s.download(id, attempt).await?))),
        }
    }
}

/// Keeps one job's uploaded store in step with the store its process writes (S3 only; a
/// no-op for a folder).
pub(crate) struct JobSync(Option<s3::Mirror>);

impl JobSync {
    /// Whether there is anything to upload (an S3 store).
    pub fn is_remote(&self) -> bool {
        self.0.is_some()
    }

    /// Uploads the store if it names a newer checkpoint than the last upload (while the job
    /// runs); returns the step uploaded.
    pub async fn checkpoint(&mut self) -> Result<Option<u64>, StoreError> {
        match &mut self.0 {
            Some(m) => m.checkpoint().await,
            None => Ok(None),
        }
    }

    /// Uploads the whole store after the run ended (deleting objects of files the run
    /// removed), then removes the scratch copy.
    pub async fn finish(self) -> Result<(), StoreError> {
        match self.0 {
            Some(m) => m.finish().await,
            None => Ok(()),
        }
    }

    /// Removes the scratch copy without uploading (the run lost its lease: another worker
    /// owns the job now).
    pub async fn discard(self) {
        if let Some(m) = self.0 {
            m.discard().await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse_or_say_why_not() {
        assert_eq!(
            StoreLocation::parse("s3://mpm-results/runs/2026").unwrap(),
            StoreLocation::S3 {
                bucket: "mpm-results".into(),
                prefix: "runs/2026".into()
            }
        );
        assert_eq!(
            StoreLocation::parse("s3://bucket").unwrap(),
            StoreLocation::S3 {
                bucket: "bucket".into(),
                prefix: String::new()
            }
        );
        assert_eq!(
            StoreLocation::parse("s3://bucket/p/").unwrap().to_string(),
            "s3://bucket/p"
        );
        assert_eq!(
            StoreLocation::parse("/shared/results").unwrap(),
            StoreLocation::Folder("/shared/results".into())
        );
        for bad in [
            "s3://",
            "s3:///prefix",
            "s3://Bad_Bucket/x",
            "s3://ab",
            "s3://bucket//x",
            "s3://bucket/a/../b",
            "gs://bucket/x",
            "",
        ] {
            let e = StoreLocation::parse(bad).unwrap_err();
            assert!(matches!(e, StoreError::BadLocation { .. }), "{bad}: {e}");
        }
    }
}

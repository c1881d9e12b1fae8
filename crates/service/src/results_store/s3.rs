//! Result stores in an S3-compatible bucket, through `object_store`'s S3 client: endpoint,
//! region and credentials from the AWS environment variables (`AWS_ENDPOINT_URL`,
//! `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_REGION` / `AWS_DEFAULT_REGION`),
//! path-style requests, plain HTTP allowed when the endpoint is `http://` (a local server).
//!
//! A job's store is the objects `<prefix>/<id>/results.zarr/<key>`, `<key>` being the file's
//! path inside the store folder the job's process writes in this machine's scratch folder.

use super::local::walk;
use super::{RESULTS, StoreError};
use futures_util::{StreamExt, TryStreamExt, stream};
use object_store::aws::{AmazonS3, AmazonS3Builder};
use object_store::path::Path as Key;
use object_store::{ObjectStore, ObjectStoreExt, PutPayload};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

/// Requests in flight at once for one store's upload or download.
const PARALLEL: usize = 8;

/// The render cache's folder inside the scratch folder (never a job id, which is a UUID).
const RENDER_CACHE: &str = "render-cache";

/// A file's size and modification time: an unchanged stamp needs no new upload.
type Stamp = (u64, Option<SystemTime>);

/// The stores of one bucket and prefix.
#[derive(Debug)]
pub(crate) struct S3Store {
    client: Arc<AmazonS3>,
    /// The key prefix (no leading or trailing `/`).
    prefix: String,
    /// This process's scratch folder: jobs write here before their stores are uploaded.
    pub scratch: PathBuf,
}

/// The endpoint the client will use, as the AWS tools read it.
fn endpoint() -> Option<String> {
    ["AWS_ENDPOINT_URL_S3", "AWS_ENDPOINT_URL", "AWS_ENDPOINT"]
        .iter()
        .find_map(|k| std::env::var(k).ok().filter(|v| !v.is_empty()))
}

impl S3Store {
    /// Builds the client from the environment and checks that the bucket answers a listing
    /// (a missing bucket is [`StoreError::NoBucket`]).
    pub async fn open(bucket: &str, prefix: &str, scratch: &Path) -> Result<Self, StoreError> {
        let endpoint = endpoint();
        let mut builder = AmazonS3Builder::from_env()
            .with_bucket_name(bucket)
            .with_virtual_hosted_style_request(false);
        if endpoint
            .as_deref()
            .is_some_and(|e| e.starts_with("http://"))
        {
            builder = builder.with_allow_http(true);
        }
        let client = Arc::new(builder.build()?);
        std::fs::create_dir_all(scratch).map_err(|e| StoreError::io(scratch, e))?;
        let store = Self {
            client,
            prefix: prefix.to_string(),
            scratch: scratch.to_path_buf(),
        };
        match store
            .client
            .list_with_delimiter(Some(&Key::from(prefix)))
            .await
        {
            Ok(_) => Ok(store),
            // S3 answers a listing of a missing bucket with 404 `NoSuchBucket`, which
            // object_store passes on as a generic error carrying the body.
            Err(e)
                if matches!(e, object_store::Error::NotFound { .. })
                    || e.to_string().contains("NoSuchBucket") =>
            {
                Err(StoreError::NoBucket {
                    bucket: bucket.to_string(),
                    endpoint: endpoint.unwrap_or_else(|| "AWS S3".into()),
                    message: "the server answered NoSuchBucket".into(),
                })
            }
            Err(e) => Err(e.into()),
        }
    }

    /// The key of a job's store: `<prefix>/<id>/results.zarr`.
    fn base(&self, id: &str) -> Key {
        Key::from(self.prefix.as_str()).join(id).join(RESULTS)
    }

    /// The bytes of one object of a job's store; `None` when missing.
    pub async fn read(&self, id: &str, key: &str) -> Result<Option<Vec<u8>>, StoreError> {
        match self.client.get(&key_of(&self.base(id), key)).await {
            Ok(found) => Ok(Some(found.bytes().await?.to_vec())),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Whether a job's store has the object `key`.
    pub async fn exists(&self, id: &str, key: &str) -> Result<bool, StoreError> {
        match self.client.head(&key_of(&self.base(id), key)).await {
            Ok(_) => Ok(true),
            Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(e.into()),
        }
    }

    /// Every key of a job's store, sorted.
    pub async fn list(&self, id: &str) -> Result<Vec<String>, StoreError> {
        let base = self.base(id);
        let mut keys: Vec<String> = self
            .client
            .list(Some(&base))
            .try_filter_map(|meta| std::future::ready(Ok(relative(&meta.location, &base))))
            .try_collect()
            .await?;
        keys.sort();
        Ok(keys)
    }

    /// Replaces the job's scratch folder with the store an earlier attempt uploaded (none
    /// before the first attempt: nothing is asked then) and returns the mirror that uploads
    /// it again as the run writes. The mirror knows every object of the store from here on.
    pub async fn download(&self, id: &str, attempt: i64) -> Result<Mirror, StoreError> {
        let job_dir = self.scratch.join(id);
        remove_dir(&job_dir).await?;
        let dir = job_dir.join(RESULTS);
        tokio::fs::create_dir_all(&dir)
            .await
            .map_err(|e| StoreError::io(&dir, e))?;
        let base = self.base(id);
        let sent = if attempt > 1 {
            fetch(&self.client, &base, &dir, |_| true).await?
        } else {
            Vec::new()
        };
        let checkpoint = checkpoint_of(&dir.join("zarr.json"))
            .await
            .map(|(_, step)| step);
        Ok(Mirror {
            client: self.client.clone(),
            base,
            job_dir,
            dir,
            sent: sent.into_iter().collect(),
            checkpoint,
        })
    }

    /// The root `zarr.json` and the objects under the group `group` of job `source`'s store,
    /// downloaded into the folder `dir` (a store holding only that group, for a job that
    /// starts from it).
    pub async fn fetch_group(
        &self,
        source: &str,
        group: &str,
        dir: &Path,
    ) -> Result<usize, StoreError> {
        remove_dir(dir).await?;
        let below = format!("{group}/");
        let got = fetch(&self.client, &self.base(source), dir, |key| {
            key == "zarr.json" || key.starts_with(&below)
        })
        .await?;
        Ok(got.len())
    }

    /// A job's store (without its checkpoints) in a local folder: kept in the render cache
    /// for a job that has ended, a temporary folder (removed with the returned guard) for one
    /// that may still change.
    pub async fn local_copy(
        &self,
        id: &str,
        ended: bool,
    ) -> Result<(PathBuf, Option<tempfile::TempDir>), StoreError> {
        let cache = self.scratch.join(RENDER_CACHE);
        let kept = cache.join(id);
        if ended && tokio::fs::try_exists(&kept).await.unwrap_or(false) {
            return Ok((kept.join(RESULTS), None));
        }
        tokio::fs::create_dir_all(&cache)
            .await
            .map_err(|e| StoreError::io(&cache, e))?;
        let temp = tempfile::Builder::new()
            .prefix(".download")
            .tempdir_in(&cache)
            .map_err(|e| StoreError::io(&cache, e))?;
        let dir = temp.path().join(RESULTS);
        fetch(&self.client, &self.base(id), &dir, |key| {
            !key.starts_with("checkpoints/")
        })
        .await?;
        if !ended {
            return Ok((dir, Some(temp)));
        }
        // Complete copies appear in the cache whole (a rename), so a reader never sees half.
        let done = temp.keep();
        if tokio::fs::rename(&done, &kept).await.is_err() {
            // Another request cached it first.
            remove_dir(&done).await?;
        }
        Ok((kept.join(RESULTS), None))
    }
}

/// `location`'s path below `base` as a `/`-separated key, when every part is a plain name.
fn relative(location: &Key, base: &Key) -> Option<String> {
    let parts: Vec<String> = location
        .prefix_match(base)?
        .map(|p| p.as_ref().to_string())
        .collect();
    let plain = |p: &String| !p.is_empty() && p != "." && p != ".." && !p.contains('\\');
    (!parts.is_empty() && parts.iter().all(plain)).then(|| parts.join("/"))
}

/// Removes a folder and everything in it; a missing folder is fine.
async fn remove_dir(dir: &Path) -> Result<(), StoreError> {
    match tokio::fs::remove_dir_all(dir).await {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StoreError::io(dir, e)),
        _ => Ok(()),
    }
}

fn stamp_of(meta: &std::fs::Metadata) -> Stamp {
    (meta.len(), meta.modified().ok())
}

/// Downloads every object under `base` whose key passes `keep` into the folder `dir`;
/// returns each written file's key and stamp.
async fn fetch(
    client: &Arc<AmazonS3>,
    base: &Key,
    dir: &Path,
    keep: impl Fn(&str) -> bool,
) -> Result<Vec<(String, Stamp)>, StoreError> {
    let keys: Vec<(Key, String)> = client
        .list(Some(base))
        .try_filter_map(|meta| {
            let key = relative(&meta.location, base).filter(|k| keep(k));
            std::future::ready(Ok(key.map(|k| (meta.location, k))))
        })
        .try_collect()
        .await?;
    stream::iter(keys)
        .map(|(location, key)| {
            let (client, path) = (client.clone(), dir.join(&key));
            async move {
                let bytes = client.get(&location).await?.bytes().await?;
                if let Some(parent) = path.parent() {
                    tokio::fs::create_dir_all(parent)
                        .await
                        .map_err(|e| StoreError::io(parent, e))?;
                }
                tokio::fs::write(&path, &bytes)
                    .await
                    .map_err(|e| StoreError::io(&path, e))?;
                let meta = tokio::fs::metadata(&path)
                    .await
                    .map_err(|e| StoreError::io(&path, e))?;
                Ok::<_, StoreError>((key, stamp_of(&meta)))
            }
        })
        .buffer_unordered(PARALLEL)
        .try_collect()
        .await
}

/// A file's bytes read while it did not change (the job's process may be rewriting it):
/// its stamp before and after the read agree, or the last of a few tries. `None` when the
/// file is gone.
async fn read_settled(path: &Path) -> Result<Option<(Vec<u8>, Stamp)>, StoreError> {
    let stat = |p: &Path| {
        let p = p.to_path_buf();
        async move {
            match tokio::fs::metadata(&p).await {
                Ok(m) => Ok(Some(stamp_of(&m))),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(StoreError::io(&p, e)),
            }
        }
    };
    let mut last = None;
    for _ in 0..5 {
        let Some(before) = stat(path).await? else {
            return Ok(None);
        };
        let bytes = match tokio::fs::read(path).await {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(StoreError::io(path, e)),
        };
        if stat(path).await? == Some(before) {
            return Ok(Some((bytes, before)));
        }
        last = Some((bytes, before));
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    Ok(last)
}

/// The checkpoint a store's root `zarr.json` names: (group path, step); `None` when it
/// names none or cannot be read whole now.
async fn checkpoint_of(root: &Path) -> Option<(String, u64)> {
    let bytes = tokio::fs::read(root).await.ok()?;
    checkpoint_in(&bytes)
}

fn checkpoint_in(root_json: &[u8]) -> Option<(String, u64)> {
    let value: serde_json::Value = serde_json::from_slice(root_json).ok()?;
    let pointer = value.get("attributes")?.get("checkpoint")?;
    Some((
        pointer.get("path")?.as_str()?.to_string(),
        pointer.get("step")?.as_u64()?,
    ))
}

/// One job's store in the scratch folder and what of it the bucket already has.
pub(crate) struct Mirror {
    client: Arc<AmazonS3>,
    /// `<prefix>/<id>/results.zarr`.
    base: Key,
    /// The job's scratch folder (removed when the run is over).
    job_dir: PathBuf,
    /// The store folder the job's process writes.
    dir: PathBuf,
    /// Keys in the bucket, with the stamp of the file each was uploaded from.
    sent: HashMap<String, Stamp>,
    /// The step of the checkpoint the uploaded root `zarr.json` names.
    checkpoint: Option<u64>,
}

impl Mirror {
    /// Uploads the store when its root names a checkpoint newer than the uploaded one.
    pub async fn checkpoint(&mut self) -> Result<Option<u64>, StoreError> {
        let Some((_, step)) = checkpoint_of(&self.dir.join("zarr.json")).await else {
            return Ok(None);
        };
        if self.checkpoint == Some(step) {
            return Ok(None);
        }
        Ok(self.sync(false).await?.filter(|&s| s == step))
    }

    /// Uploads the finished store, removes objects of files that are gone, and removes the
    /// scratch folder.
    pub async fn finish(mut self) -> Result<(), StoreError> {
        self.sync(true).await?;
        remove_dir(&self.job_dir).await
    }

    /// Removes the scratch folder, uploading nothing.
    pub async fn discard(self) {
        if let Err(e) = remove_dir(&self.job_dir).await {
            tracing::warn!(error = %e, "removing a job's scratch folder failed");
        }
    }

    /// Uploads the files that changed since their last upload, the root `zarr.json` last.
    ///
    /// While the job runs (`!ended`) its process may write a newer checkpoint and remove the
    /// older one meanwhile: the root read first is uploaded only if the checkpoint it names
    /// is still there after the other files went up, so the bucket's root always names a
    /// checkpoint whose files it has; otherwise the next call tries again. Objects of files
    /// that are gone are removed after a root was uploaded. Returns the checkpoint step the
    /// uploaded root names.
    async fn sync(&mut self, ended: bool) -> Result<Option<u64>, StoreError> {
        let root = read_settled(&self.dir.join("zarr.json")).await?;
        let named = root.as_ref().and_then(|(bytes, _)| checkpoint_in(bytes));
        // The files, and those whose stamp differs from their upload's (off the async
        // threads: a store may have many files).
        let (dir, sent) = (self.dir.clone(), self.sent.clone());
        let (files, changed) = tokio::task::spawn_blocking(move || {
            let files = walk(&dir);
            let changed: Vec<String> = files
                .iter()
                .filter(|key| key.as_str() != "zarr.json")
                .filter(|key| {
                    let now = std::fs::metadata(dir.join(key)).ok().map(|m| stamp_of(&m));
                    now.is_some() && now.as_ref() != sent.get(key.as_str())
                })
                .cloned()
                .collect();
            (files, changed)
        })
        .await
        .map_err(|e| StoreError::Io {
            path: self.dir.display().to_string(),
            error: std::io::Error::other(e),
        })?;
        let uploaded: Vec<Option<(String, Stamp)>> = stream::iter(changed)
            .map(|key| {
                let (client, base, path) =
                    (self.client.clone(), self.base.clone(), self.dir.join(&key));
                async move {
                    let Some((bytes, stamp)) = read_settled(&path).await? else {
                        return Ok(None);
                    };
                    put(&client, &base, &key, bytes).await?;
                    Ok::<_, StoreError>(Some((key, stamp)))
                }
            })
            .buffer_unordered(PARALLEL)
            .try_collect()
            .await?;
        self.sent.extend(uploaded.into_iter().flatten());
        let consistent = ended
            || named
                .as_ref()
                .is_none_or(|(path, _)| self.dir.join(path).is_dir());
        if !consistent {
            return Ok(None);
        }
        if let Some((bytes, stamp)) = root {
            put(&self.client, &self.base, "zarr.json", bytes).await?;
            self.sent.insert("zarr.json".into(), stamp);
        }
        let local: HashSet<&String> = files.iter().collect();
        let stale: Vec<String> = self
            .sent
            .keys()
            .filter(|k| !local.contains(k))
            .cloned()
            .collect();
        for key in stale {
            self.sent.remove(&key);
            match self.client.delete(&key_of(&self.base, &key)).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
        let step = named.map(|(_, step)| step);
        self.checkpoint = step;
        Ok(step)
    }
}

/// The object key of a store's relative `key`.
fn key_of(base: &Key, key: &str) -> Key {
    key.split('/').fold(base.clone(), |k, part| k.join(part))
}

async fn put(
    client: &Arc<AmazonS3>,
    base: &Key,
    key: &str,
    bytes: Vec<u8>,
) -> Result<(), StoreError> {
    client
        .put(&key_of(base, key), PutPayload::from(bytes))
        .await?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_below_a_store_are_plain_relative_paths() {
        let base = Key::from("runs/job/results.zarr");
        let key = |k: &str| relative(&Key::from(k), &base);
        assert_eq!(
            key("runs/job/results.zarr/particles/x/c/0/0").as_deref(),
            Some("particles/x/c/0/0")
        );
        assert_eq!(
            key("runs/job/results.zarr/zarr.json").as_deref(),
            Some("zarr.json")
        );
        assert_eq!(key("runs/job/results.zarr"), None, "the base itself");
        assert_eq!(key("runs/other/results.zarr/zarr.json"), None);
        assert_eq!(key_of(&base, "a/b").as_ref(), "runs/job/results.zarr/a/b");
    }

    #[test]
    fn the_checkpoint_pointer_is_read_from_the_root_metadata() {
        let root = br#"{"zarr_format":3,"node_type":"group","attributes":
            {"checkpoint":{"path":"checkpoints/800","step":800,"time":0.6,"frames":5}}}"#;
        assert_eq!(checkpoint_in(root), Some(("checkpoints/800".into(), 800)));
        assert_eq!(checkpoint_in(br#"{"attributes":{}}"#), None);
        // Half-written metadata (read while the job's process rewrites it) names nothing.
        assert_eq!(checkpoint_in(&root[..40]), None);
    }
}

//! A map's tiles on disk: where [`isoline_map::Map`] puts the tiles it holds no longer
//! in memory, one file a tile, in a directory of its own removed when the store goes.
//!
//! A run that is killed cannot remove its directory; the next store made in the same
//! parent does. Each directory holds a `lock` file its store keeps locked (an advisory
//! lock the system releases when the process ends, however it ends): a directory whose
//! lock can be taken belongs to no living run.

use std::path::{Path, PathBuf};

use isoline_map::{TileKey, TileStore};

/// A [`TileStore`] in a directory: `tile_I_J.bin` a tile. The directory is created, and
/// removed with its files when the store is dropped.
#[derive(Debug)]
pub struct DiskTiles {
    dir: PathBuf,
    /// Held locked while the store lives.
    _lock: std::fs::File,
}

/// The prefix of a store's directory name.
const PREFIX: &str = "isoline-tiles-";

impl DiskTiles {
    /// A store in a new directory under `parent` (the system's temporary directory when
    /// `None`).
    pub fn new(parent: Option<&Path>) -> std::io::Result<DiskTiles> {
        let parent = parent.map_or_else(std::env::temp_dir, Path::to_path_buf);
        std::fs::create_dir_all(&parent)?;
        remove_stale(&parent);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        for attempt in 0..1000u32 {
            let dir = parent.join(format!("{PREFIX}{}-{nanos}-{attempt}", std::process::id()));
            match std::fs::create_dir(&dir) {
                Ok(()) => {
                    let lock = std::fs::File::create(dir.join("lock"))
                        .and_then(|f| f.try_lock().map_err(std::io::Error::other).map(|()| f));
                    return match lock {
                        Ok(f) => Ok(DiskTiles { dir, _lock: f }),
                        Err(e) => {
                            let _ = std::fs::remove_dir_all(&dir);
                            Err(e)
                        }
                    };
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
        Err(std::io::Error::other("no free name for a tile directory"))
    }

    /// The directory the tiles are in.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn path(&self, key: TileKey) -> PathBuf {
        self.dir.join(format!("tile_{}_{}.bin", key.0, key.1))
    }
}

/// Removes the tile directories under `parent` that no living store holds: their lock
/// can be taken, or (made before a lock was) they are older than a minute and have none.
fn remove_stale(parent: &Path) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        let dir = e.path();
        let named = e
            .file_name()
            .to_str()
            .is_some_and(|n| n.starts_with(PREFIX));
        if !named || !dir.is_dir() {
            continue;
        }
        let stale = match std::fs::File::open(dir.join("lock")) {
            Ok(f) => f.try_lock().is_ok(),
            Err(_) => e
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age.as_secs() > 60),
        };
        if stale {
            tracing::info!(dir = %dir.display(), "removing the tiles a killed run left");
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
}

impl TileStore for DiskTiles {
    fn put(&mut self, key: TileKey, bytes: Vec<u8>) -> Result<(), String> {
        let path = self.path(key);
        std::fs::write(&path, bytes).map_err(|e| format!("writing {}: {e}", path.display()))
    }

    fn take(&mut self, key: TileKey) -> Result<Option<Vec<u8>>, String> {
        let path = self.path(key);
        match std::fs::read(&path) {
            Ok(b) => {
                let _ = std::fs::remove_file(&path);
                Ok(Some(b))
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(format!("reading {}: {e}", path.display())),
        }
    }
}

impl Drop for DiskTiles {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tile_put_away_comes_back_once_and_the_directory_goes_with_the_store() {
        let parent = tempfile::tempdir().unwrap();
        let mut store = DiskTiles::new(Some(parent.path())).unwrap();
        let dir = store.dir().to_path_buf();
        store.put((-3, 4), vec![1, 2, 3]).unwrap();
        assert_eq!(store.take((-3, 4)).unwrap(), Some(vec![1, 2, 3]));
        assert_eq!(store.take((-3, 4)).unwrap(), None);
        store.put((0, 0), vec![9]).unwrap();
        drop(store);
        assert!(!dir.exists());
    }

    #[test]
    fn a_killed_runs_tiles_are_removed_by_the_next_store_and_a_living_ones_are_not() {
        let parent = tempfile::tempdir().unwrap();
        let mut living = DiskTiles::new(Some(parent.path())).unwrap();
        living.put((5, 5), vec![1]).unwrap();
        // What a killed run leaves: its directory and an unlocked lock file.
        let dead = parent.path().join(format!("{PREFIX}1-2-3"));
        std::fs::create_dir(&dead).unwrap();
        std::fs::write(dead.join("lock"), b"").unwrap();
        std::fs::write(dead.join("tile_0_0.bin"), vec![0u8; 1000]).unwrap();
        let other = parent.path().join("keep-me");
        std::fs::create_dir(&other).unwrap();
        let next = DiskTiles::new(Some(parent.path())).unwrap();
        assert!(!dead.exists());
        assert!(living.dir().exists() && next.dir().exists() && other.exists());
    }
}

//! A map's tiles on disk: where [`isoline_core::Map`] puts the tiles it holds no longer
//! in memory, one file a tile, in a directory of its own removed when the store goes.

use std::path::{Path, PathBuf};

use isoline_core::{TileKey, TileStore};

/// A [`TileStore`] in a directory: `tile_I_J.bin` a tile. The directory is created, and
/// removed with its files when the store is dropped.
#[derive(Debug)]
pub struct DiskTiles {
    dir: PathBuf,
}

impl DiskTiles {
    /// A store in a new directory under `parent` (the system's temporary directory when
    /// `None`).
    pub fn new(parent: Option<&Path>) -> std::io::Result<DiskTiles> {
        let parent = parent.map_or_else(std::env::temp_dir, Path::to_path_buf);
        std::fs::create_dir_all(&parent)?;
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        for attempt in 0..1000u32 {
            let dir = parent.join(format!(
                "isoline-tiles-{}-{nanos}-{attempt}",
                std::process::id()
            ));
            match std::fs::create_dir(&dir) {
                Ok(()) => return Ok(DiskTiles { dir }),
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
}

//! The staging directory: outputs are written under `<output.dir>/.chunkc-staging/` and renamed
//! into place only when every profile succeeded. Dropping a [`Staging`] without committing
//! removes everything it created, so a failed build leaves no partial output behind.

use std::path::{Path, PathBuf};

use crate::error::{IoContext, Result};

pub const STAGING_DIR: &str = ".chunkc-staging";

pub struct Staging {
    out_dir: PathBuf,
    dir: PathBuf,
    created_out_dir: bool,
    committed: bool,
}

impl Staging {
    pub fn new(out_dir: &Path) -> Result<Self> {
        let created_out_dir = !out_dir.exists();
        std::fs::create_dir_all(out_dir).at("create output directory", out_dir)?;
        let dir = out_dir.join(STAGING_DIR);
        if dir.exists() {
            // Left by an interrupted build: nothing in it was ever in place.
            std::fs::remove_dir_all(&dir).at("remove stale staging directory", &dir)?;
        }
        std::fs::create_dir(&dir).at("create staging directory", &dir)?;
        Ok(Staging {
            out_dir: out_dir.to_path_buf(),
            dir,
            created_out_dir,
            committed: false,
        })
    }

    /// The staging directory of one profile (created).
    pub fn profile_dir(&self, name: &str) -> Result<PathBuf> {
        let dir = self.dir.join(name);
        std::fs::create_dir_all(&dir).at("create", &dir)?;
        Ok(dir)
    }

    /// Moves every staged profile into place, replacing the previous output of that profile.
    pub fn commit(mut self, profiles: &[String]) -> Result<()> {
        for name in profiles {
            let staged = self.dir.join(name);
            let target = self.out_dir.join(name);
            if target.exists() {
                let old = self.dir.join(format!("{name}.old"));
                std::fs::rename(&target, &old).at("move aside", &target)?;
            }
            std::fs::rename(&staged, &target).at("move into place", &target)?;
        }
        std::fs::remove_dir_all(&self.dir).at("remove", &self.dir)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        let _ = std::fs::remove_dir_all(&self.dir);
        if self.created_out_dir {
            // Only removes it if nothing else was put there meanwhile.
            let _ = std::fs::remove_dir(&self.out_dir);
        }
    }
}

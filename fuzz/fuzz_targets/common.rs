//! A scratch folder per fuzzing process, for readers that take paths.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The process's scratch folder, made once, holding an image file at the
/// paths fuzzed manifests most often name.
pub fn scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("pirouette-fuzz-{}", std::process::id()));
        for name in [
            "frames/s00/000.png",
            "frames/s00/001.png",
            "frames/s01/000.png",
            "a.png",
        ] {
            let path = dir.join(name);
            std::fs::create_dir_all(path.parent().expect("a parent")).expect("scratch folder");
            std::fs::write(&path, b"").expect("scratch image");
        }
        std::fs::create_dir_all(dir.join("truth")).expect("scratch folder");
        dir
    })
}

//! Output files written whole or not at all.

use super::VizError;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A file being written: the bytes go to a temporary file beside the target, which
/// [`OutputFile::commit`] renames onto the target. Dropped without a commit (an error on the
/// way), the temporary file is removed and the target is left as it was: a reader never sees a
/// half-written file under the target's name.
#[derive(Debug)]
pub struct OutputFile {
    target: PathBuf,
    temporary: PathBuf,
    file: Option<std::fs::File>,
}

impl OutputFile {
    /// Opens the temporary file for `target`, whose name must end in `.extension` (any case).
    /// Creating it now checks that the directory exists and can be written, before any work.
    pub fn create(target: &Path, extension: &str) -> Result<Self, VizError> {
        let fail = |message: String| VizError::Output { file: target.display().to_string(), message };
        if !target.extension().is_some_and(|e| e.eq_ignore_ascii_case(extension)) {
            return Err(fail(format!("the output file must end in .{extension}")));
        }
        if target.is_dir() {
            return Err(fail("is a directory".to_string()));
        }
        let name = target.file_name().ok_or_else(|| fail("not a file name".to_string()))?;
        let mut temporary_name = std::ffi::OsString::from(".");
        temporary_name.push(name);
        temporary_name.push(format!(".{}.partial", std::process::id()));
        let temporary = target.with_file_name(temporary_name);
        let file = std::fs::File::create(&temporary).map_err(|e| fail(format!("cannot write: {e}")))?;
        Ok(Self { target: target.to_path_buf(), temporary, file: Some(file) })
    }

    /// The target path.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Writes `bytes` to the temporary file and renames it onto the target.
    pub fn commit(mut self, bytes: &[u8]) -> Result<(), VizError> {
        let fail = |e: std::io::Error| VizError::Output {
            file: self.target.display().to_string(),
            message: format!("cannot write: {e}"),
        };
        let mut file = self.file.take().expect("an OutputFile is committed once");
        file.write_all(bytes).and_then(|()| file.sync_all()).map_err(fail)?;
        drop(file);
        std::fs::rename(&self.temporary, &self.target).map_err(fail)?;
        Ok(())
    }
}

impl Drop for OutputFile {
    fn drop(&mut self) {
        if self.file.take().is_some() || self.temporary.exists() {
            let _ = std::fs::remove_file(&self.temporary);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_replaces_and_drop_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("gelenk-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("a.glb");
        OutputFile::create(&target, "glb").unwrap().commit(b"one").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"one");
        // An abandoned write leaves the old file and no temporary file.
        drop(OutputFile::create(&target, "glb").unwrap());
        assert_eq!(std::fs::read(&target).unwrap(), b"one");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        assert!(OutputFile::create(&dir.join("a.gltf"), "glb").is_err());
        assert!(OutputFile::create(&dir.join("missing/a.glb"), "glb").is_err());
        std::fs::create_dir(dir.join("b.glb")).unwrap();
        let error = OutputFile::create(&dir.join("b.glb"), "glb").unwrap_err();
        assert!(error.to_string().ends_with("b.glb: is a directory"), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

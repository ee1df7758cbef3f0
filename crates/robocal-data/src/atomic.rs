//! Atomic output: write beside the destination, then rename over it, so a failure never leaves a
//! half-written file and an existing file stays as it was.

use std::io::{BufWriter, Write};
use std::path::Path;

use crate::error::{DataError, Result};

/// Writes a file through `fill` into a temporary file in the destination's folder and renames it
/// into place only when everything succeeded.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let err = |source| DataError::Write {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".robocal-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(err)?;
    {
        let mut w = BufWriter::new(tmp.as_file());
        fill(&mut w).map_err(err)?;
        w.flush().map_err(err)?;
    }
    tmp.as_file().sync_all().map_err(err)?;
    set_mode(tmp.path(), 0o644).map_err(err)?;
    tmp.persist(path).map_err(|e| err(e.error))?;
    Ok(())
}

/// Writes a whole directory atomically: `fill` writes into a fresh temporary directory beside
/// `out`, which then replaces `out` (an existing `out` is moved aside and removed only after the
/// new one is in place). When `fill` fails, `out` is left exactly as it was. `fill` may fail with
/// any error that a [`DataError`] converts into, so callers writing their own file kinds keep
/// their own errors.
pub fn write_dir_atomically<E: From<DataError>>(
    out: &Path,
    fill: impl FnOnce(&Path) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let err = |source| DataError::Write {
        path: out.to_path_buf(),
        source,
    };
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => Path::new(".").to_path_buf(),
    };
    std::fs::create_dir_all(&parent).map_err(err)?;
    if out.exists() && !out.is_dir() {
        return Err(err(std::io::Error::other("exists and is not a directory")).into());
    }
    let tmp = tempfile::Builder::new()
        .prefix(".robocal-")
        .tempdir_in(&parent)
        .map_err(err)?;
    fill(tmp.path())?;
    set_mode(tmp.path(), 0o755).map_err(err)?;
    let new = tmp.keep();
    if out.exists() {
        let mut old = new.clone().into_os_string();
        old.push(".old");
        let old = std::path::PathBuf::from(old);
        std::fs::rename(out, &old).map_err(err)?;
        if let Err(e) = std::fs::rename(&new, out) {
            // Put the previous directory back before reporting.
            let _ = std::fs::rename(&old, out);
            let _ = std::fs::remove_dir_all(&new);
            return Err(err(e).into());
        }
        std::fs::remove_dir_all(&old).map_err(err)?;
    } else if let Err(e) = std::fs::rename(&new, out) {
        let _ = std::fs::remove_dir_all(&new);
        return Err(err(e).into());
    }
    Ok(())
}

/// Writes `text` to the file `name` inside `dir`, the temporary directory that
/// [`write_dir_atomically`] hands to its `fill`; errors name the file's final place, `out/name`.
pub fn write_text_in(dir: &Path, out: &Path, name: &str, text: &str) -> Result<()> {
    std::fs::write(dir.join(name), text).map_err(|source| DataError::Write {
        path: out.join(name),
        source,
    })
}

/// Temporary files and folders are private (0600/0700); outputs get the usual modes.
#[cfg(unix)]
fn set_mode(path: &Path, mode: u32) -> std::io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
}

#[cfg(not(unix))]
fn set_mode(_path: &Path, _mode: u32) -> std::io::Result<()> {
    Ok(())
}

//! Results written atomically. A command writes every file into a temporary directory beside
//! `--out DIR` (same parent, `.DIR.tmp-<pid>`); [`OutDir::commit`] then replaces DIR as a
//! whole: the old DIR is renamed aside (`.DIR.old-<pid>`), the new one renamed in, the old
//! one removed. So DIR holds one run's complete results, or the previous run's untouched; a
//! run that fails (or is dropped before `commit`) removes its temporary directory. A file
//! outside DIR (`--pcap FILE`) is written to `.FILE.tmp-<pid>` beside it and renamed after
//! DIR; inside DIR it goes into the new directory with the rest.
//!
//! A file named by an option that is a symbolic link is written where the link points (the
//! link stays); one that is not a regular file (`/dev/stdout`, a FIFO, a device) is written
//! straight to, with nothing renamed over it.
//!
//! An existing DIR is replaced only when it is empty or holds a result of ringsync (a
//! `summary.json`, a `sweep.csv`, or the `scenario.toml` every run writes), so that `--out .`
//! or `--out ~` cannot remove anything else.
//! Temporary directories left by a killed run (whose process is gone) are removed by the
//! next run into the same DIR.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Files at the top of a directory that mark it as ringsync's results, safe to replace.
const RESULT_MARKERS: &[&str] = &["summary.json", "sweep.csv"];

/// Where a file named by an option goes.
#[derive(Debug, PartialEq)]
enum Target {
    /// A regular file, or none yet: written beside it, then renamed into place. The path
    /// has its symbolic links followed, so that a link stays a link.
    File(PathBuf),
    /// A device, a FIFO or a socket (`/dev/stdout`): written straight to.
    Special(PathBuf),
}

/// Where the file `path` goes (see [`Target`]); a directory, or a path through a file, is
/// refused.
fn target(path: &Path) -> Result<Target> {
    let mut p = path.to_path_buf();
    // A link that points at nothing yet: follow it to where the file will be.
    for _ in 0..40 {
        match std::fs::metadata(&p) {
            Ok(m) if m.is_dir() => {
                return Err(Error::Input(format!(
                    "{} is a directory, not a file",
                    path.display()
                )));
            }
            Ok(m) if m.is_file() => {
                let real = p
                    .canonicalize()
                    .map_err(|e| failure(e, format!("cannot resolve {}", path.display())))?;
                return Ok(Target::File(real));
            }
            Ok(_) => return Ok(Target::Special(p)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => match std::fs::read_link(&p) {
                Ok(to) => {
                    p = match p.parent() {
                        Some(dir) if to.is_relative() => dir.join(to),
                        _ => to,
                    }
                }
                Err(_) => {
                    not_under_a_file(path, &p)?;
                    return Ok(Target::File(p));
                }
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotADirectory => {
                not_under_a_file(path, &p)?;
                return Err(failure(e, format!("cannot write {}", path.display())));
            }
            Err(e) => return Err(failure(e, format!("cannot write {}", path.display()))),
        }
    }
    Err(Error::Input(format!(
        "{} is a chain of more than 40 symbolic links",
        path.display()
    )))
}

/// Refuses `p` (given as `shown`) when one of its ancestors is a file: nothing can be
/// created below it.
fn not_under_a_file(shown: &Path, p: &Path) -> Result<()> {
    if let Some(file) = p.ancestors().skip(1).find(|a| a.is_file()) {
        return Err(Error::Input(format!(
            "{}: {} is a file, not a directory",
            shown.display(),
            file.display()
        )));
    }
    Ok(())
}

/// A results directory being written; see the module documentation.
#[derive(Debug)]
pub struct OutDir {
    /// Where the results go (absolute, symbolic links resolved).
    path: PathBuf,
    /// Where they are written until [`OutDir::commit`].
    tmp: PathBuf,
    /// Files outside `path`, written beside their places: (temporary, final).
    beside: Vec<(PathBuf, PathBuf)>,
    /// Whether `tmp` has become `path`.
    committed: bool,
}

/// `.{name}.{what}-{pid}` beside `path`.
fn sibling(path: &Path, what: &str, pid: u32) -> PathBuf {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!(".{name}.{what}-{pid}"))
}

fn failure(e: std::io::Error, what: String) -> Error {
    Error::io(what, e)
}

/// `path` made absolute with its longest existing ancestor's symbolic links resolved, so
/// that two spellings of one place compare equal.
fn resolved(path: &Path) -> Result<PathBuf> {
    let abs = std::path::absolute(path)
        .map_err(|e| failure(e, format!("cannot resolve {}", path.display())))?;
    let mut rest = Vec::new();
    let mut at = abs.as_path();
    loop {
        if let Ok(real) = at.canonicalize() {
            return Ok(rest.into_iter().rev().fold(real, |p, c| p.join(c)));
        }
        match (at.parent(), at.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                at = parent;
            }
            _ => return Ok(abs),
        }
    }
}

/// Removes `.{name}.tmp-<pid>` and `.{name}.old-<pid>` beside `path` whose process is gone.
fn remove_stale(path: &Path) {
    let (Some(parent), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    let name = name.to_string_lossy();
    for entry in entries.flatten() {
        let file = entry.file_name();
        let file = file.to_string_lossy();
        let pid = [".tmp-", ".old-"].iter().find_map(|w| {
            file.strip_prefix(&format!(".{name}{w}"))
                .and_then(|p| p.parse::<u32>().ok())
        });
        if let Some(pid) = pid
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Whether an existing directory may be replaced: empty, or a ringsync result.
fn replaceable(dir: &Path) -> Result<bool> {
    let mut entries =
        std::fs::read_dir(dir).map_err(|e| failure(e, format!("cannot read {}", dir.display())))?;
    Ok(entries.next().is_none()
        || RESULT_MARKERS.iter().any(|m| dir.join(m).is_file())
        || ringsync_model::bounded::read_text(
            &dir.join(crate::identify::SCENARIO_FILE),
            1 << 20,
            "a run's scenario",
        )
        .is_ok_and(|t| t.starts_with(crate::identify::SCENARIO_HEADER)))
}

impl OutDir {
    /// Checks `path` (`option` names it in errors) and creates the temporary directory
    /// beside it, creating missing parents.
    pub fn create(option: &str, path: &Path) -> Result<Self> {
        let shown = path.display();
        let path = resolved(path)?;
        if path.file_name().is_none() {
            return Err(Error::Input(format!(
                "{option} {shown} names no directory that could be replaced"
            )));
        }
        if path.exists() {
            if !path.is_dir() {
                return Err(Error::Input(format!(
                    "{option} {shown} exists and is not a directory"
                )));
            }
            if !replaceable(&path)? {
                return Err(Error::Input(format!(
                    "{option} {shown} is not empty and holds no ringsync results (summary.json, sweep.csv or a run's scenario.toml): the run replaces {option} as a whole, so choose a new or empty directory"
                )));
            }
        } else if let Some(parent) = path.parent() {
            not_under_a_file(Path::new(&format!("{option} {shown}")), &path)?;
            std::fs::create_dir_all(parent)
                .map_err(|e| failure(e, format!("cannot create {}", parent.display())))?;
        }
        remove_stale(&path);
        let tmp = sibling(&path, "tmp", std::process::id());
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir(&tmp).map_err(|e| failure(e, format!("cannot create {shown}")))?;
        Ok(OutDir {
            path,
            tmp,
            beside: Vec::new(),
            committed: false,
        })
    }

    /// Writes `bytes` as the file `name` of the results.
    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> Result<()> {
        let p = self.tmp.join(name);
        if let Some(dir) = p.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| failure(e, format!("cannot create {}", dir.display())))?;
        }
        std::fs::write(&p, bytes).map_err(|e| {
            failure(
                e,
                format!("cannot write {}", self.path.join(name).display()),
            )
        })
    }

    /// Streams the file `name` of the results: `fill` writes it through a buffer, so a large
    /// output is never held whole in memory.
    pub fn write_with(
        &self,
        name: &str,
        fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
    ) -> Result<()> {
        let p = self.tmp.join(name);
        if let Some(dir) = p.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| failure(e, format!("cannot create {}", dir.display())))?;
        }
        let what = || format!("cannot write {}", self.path.join(name).display());
        let file = std::fs::File::create(&p).map_err(|e| failure(e, what()))?;
        let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
        fill(&mut w)
            .and_then(|()| std::io::Write::flush(&mut w))
            .map_err(|e| failure(e, what()))
    }

    /// Writes `bytes` to the file `path` given by an option (e.g. `--pcap`): inside the
    /// results directory with the rest, elsewhere beside its place until [`OutDir::commit`].
    pub fn write_file(&mut self, path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
        let tmp = self.stream_file(path)?;
        std::fs::write(&tmp, bytes)
            .map_err(|e| failure(e, format!("cannot write {}", path.display())))
    }

    /// Where to write the file `name` of the results while a run goes (a writer that
    /// streams it): inside the temporary directory, its parents created.
    pub fn stream_path(&self, name: &str) -> Result<PathBuf> {
        let p = self.tmp.join(name);
        if let Some(dir) = p.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| failure(e, format!("cannot create {}", dir.display())))?;
        }
        Ok(p)
    }

    /// Where to write the file `path` given by an option (e.g. `--pcap`) while a run goes:
    /// inside the results directory with the rest, elsewhere a temporary file beside its
    /// place, renamed into place by [`OutDir::commit`].
    pub fn stream_file(&mut self, path: &Path) -> Result<PathBuf> {
        let full = resolved(path)?;
        if full == self.path {
            return Err(Error::Input(format!(
                "{} is the results directory, not a file beside it",
                path.display()
            )));
        }
        if let Ok(inside) = full.strip_prefix(&self.path)
            && !inside.as_os_str().is_empty()
        {
            return self.stream_path(&inside.to_string_lossy());
        }
        let path = match target(path)? {
            Target::Special(p) => return Ok(p),
            Target::File(p) => p,
        };
        let tmp = sibling(&path, "tmp", std::process::id());
        if !self.beside.iter().any(|(t, _)| *t == tmp) {
            self.beside.push((tmp.clone(), path));
        }
        Ok(tmp)
    }

    /// Refuses an input file (the scenario) inside the results directory, which the run
    /// would replace.
    pub fn keep_out(&self, input: &Path) -> Result<()> {
        if input.is_file() && resolved(input)?.starts_with(&self.path) {
            return Err(Error::Input(format!(
                "{} is inside the results directory, which the run replaces as a whole: move it out or choose another --out",
                input.display()
            )));
        }
        Ok(())
    }

    /// Replaces the results directory by the new one, then moves the files outside it into
    /// place.
    pub fn commit(mut self) -> Result<()> {
        let old = sibling(&self.path, "old", std::process::id());
        let had_old = self.path.exists();
        if had_old {
            std::fs::rename(&self.path, &old)
                .map_err(|e| failure(e, format!("cannot replace {}", self.path.display())))?;
        }
        if let Err(e) = std::fs::rename(&self.tmp, &self.path) {
            if had_old {
                let _ = std::fs::rename(&old, &self.path);
            }
            return Err(failure(
                e,
                format!("cannot replace {}", self.path.display()),
            ));
        }
        self.committed = true;
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        while let Some((tmp, path)) = self.beside.pop() {
            std::fs::rename(&tmp, &path)
                .map_err(|e| failure(e, format!("cannot write {}", path.display())))?;
        }
        Ok(())
    }
}

impl Drop for OutDir {
    /// Removes what was not committed.
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
        for (tmp, _) in &self.beside {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Checks, before a long run, that [`write_file`] could write `path`: its directory is
/// there (nothing is created).
pub fn writable(path: &Path) -> Result<()> {
    if let Target::File(p) = target(path)?
        && let Some(dir) = p.parent()
        && !dir.as_os_str().is_empty()
        && !dir.is_dir()
    {
        return Err(Error::Input(format!(
            "{} cannot be written: its directory {} does not exist",
            path.display(),
            dir.display()
        )));
    }
    Ok(())
}

/// Writes one file atomically: to `.NAME.tmp-<pid>` beside it, then renamed into place (a
/// symbolic link is followed; a device or FIFO such as `/dev/stdout` is written straight
/// to).
pub fn write_file(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    let real = match target(path)? {
        Target::Special(p) => {
            return std::fs::OpenOptions::new()
                .write(true)
                .open(&p)
                .and_then(|mut f| std::io::Write::write_all(&mut f, bytes.as_ref()))
                .map_err(|e| failure(e, format!("cannot write {}", path.display())));
        }
        Target::File(p) => p,
    };
    let tmp = sibling(&real, "tmp", std::process::id());
    let done = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, &real));
    if let Err(e) = done {
        let _ = std::fs::remove_file(&tmp);
        return Err(failure(e, format!("cannot write {}", path.display())));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("ringsync-out-unit-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch");
        d
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .map(|r| {
                r.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    }

    #[test]
    fn commit_replaces_the_directory_as_a_whole() {
        let base = scratch("commit");
        let out = base.join("run");
        std::fs::create_dir_all(&out).expect("dir");
        std::fs::write(out.join("summary.json"), "old").expect("old");
        std::fs::write(out.join("old-figure.svg"), "old").expect("old");
        let d = OutDir::create("--out", &out).expect("create");
        d.write("summary.json", "new").expect("write");
        // Nothing visible changes before the commit.
        assert_eq!(files(&out), ["old-figure.svg", "summary.json"]);
        d.commit().expect("commit");
        assert_eq!(files(&out), ["summary.json"]);
        assert_eq!(
            std::fs::read_to_string(out.join("summary.json")).expect("read"),
            "new"
        );
        assert_eq!(files(&base), ["run"], "no temporary left beside it");
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_dropped_run_leaves_the_old_results_and_no_temporary() {
        let base = scratch("drop");
        let out = base.join("run");
        std::fs::create_dir_all(&out).expect("dir");
        std::fs::write(out.join("summary.json"), "old").expect("old");
        let pcap = base.join("run.pcapng");
        {
            let mut d = OutDir::create("--out", &out).expect("create");
            d.write("summary.json", "new").expect("write");
            d.write_file(&pcap, "pcap").expect("pcap");
        }
        assert_eq!(files(&base), ["run"]);
        assert_eq!(
            std::fs::read_to_string(out.join("summary.json")).expect("read"),
            "old"
        );
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_file_inside_the_directory_goes_with_it() {
        let base = scratch("inside");
        let out = base.join("run");
        let mut d = OutDir::create("--out", &out).expect("create");
        d.write_file(&out.join("frames.pcapng"), "pcap")
            .expect("pcap");
        d.write_file(&base.join("beside.pcapng"), "pcap")
            .expect("pcap");
        d.commit().expect("commit");
        assert_eq!(files(&out), ["frames.pcapng"]);
        assert_eq!(files(&base), ["beside.pcapng", "run"]);
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn only_empty_or_result_directories_are_replaced() {
        let base = scratch("guard");
        std::fs::write(base.join("notes.txt"), "mine").expect("write");
        let e = OutDir::create("--out", &base).expect_err("not a result");
        assert!(matches!(e, Error::Input(m) if m.contains("holds no ringsync results")));
        let e = OutDir::create("--out", &base.join("notes.txt")).expect_err("a file");
        assert!(matches!(e, Error::Input(m) if m.contains("is not a directory")));
        assert_eq!(files(&base), ["notes.txt"]);
        // A temporary of a process that is gone is cleared by the next run.
        let stale = base.join(".run.tmp-4294967295");
        std::fs::create_dir_all(&stale).expect("stale");
        OutDir::create("--out", &base.join("run"))
            .expect("create")
            .commit()
            .expect("commit");
        assert_eq!(files(&base), ["notes.txt", "run"]);
        // A run's own directory, whatever it was asked to write, is a result.
        let run = base.join("trace-only");
        std::fs::create_dir_all(&run).expect("dir");
        std::fs::write(run.join("trace.parquet"), "x").expect("write");
        std::fs::write(
            run.join(crate::identify::SCENARIO_FILE),
            format!("{}paper-2015.\n", crate::identify::SCENARIO_HEADER),
        )
        .expect("write");
        OutDir::create("--out", &run)
            .expect("a run's directory")
            .commit()
            .expect("commit");
        // Nothing can be created below a file.
        let e = OutDir::create("--out", &base.join("notes.txt").join("run")).expect_err("file");
        assert!(
            matches!(&e, Error::Input(m) if m.contains("notes.txt is a file, not a directory")),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&base);
    }

    /// A file given by an option: a link is written through (it stays a link), a device is
    /// written straight to (it stays a device), a directory or a path through a file is
    /// refused.
    #[test]
    fn single_files_keep_what_their_path_is() {
        use std::os::unix::fs::FileTypeExt;
        let base = scratch("single");
        let real = base.join("real.svg");
        std::fs::write(&real, "old").expect("write");
        let link = base.join("link.svg");
        std::os::unix::fs::symlink("real.svg", &link).expect("link");
        write_file(&link, "new").expect("through the link");
        assert!(
            std::fs::symlink_metadata(&link)
                .expect("meta")
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(&real).expect("read"), "new");
        // A link to a file not there yet creates the file and keeps the link.
        let dangling = base.join("later.svg");
        std::os::unix::fs::symlink("made.svg", &dangling).expect("link");
        write_file(&dangling, "made").expect("through a dangling link");
        assert_eq!(
            std::fs::read_to_string(base.join("made.svg")).expect("read"),
            "made"
        );
        assert!(
            std::fs::symlink_metadata(&dangling)
                .expect("meta")
                .file_type()
                .is_symlink()
        );
        let null = Path::new("/dev/null");
        write_file(null, "discarded").expect("a device");
        assert!(
            std::fs::metadata(null)
                .expect("meta")
                .file_type()
                .is_char_device()
        );
        let mut d = OutDir::create("--out", &base.join("run")).expect("create");
        assert_eq!(d.stream_file(null).expect("stream"), null);
        d.commit().expect("commit");
        assert!(
            std::fs::metadata(null)
                .expect("meta")
                .file_type()
                .is_char_device()
        );
        let e = write_file(&base, "x").expect_err("a directory");
        assert!(
            matches!(&e, Error::Input(m) if m.contains("is a directory")),
            "{e}"
        );
        let e = write_file(&real.join("x.svg"), "x").expect_err("below a file");
        assert!(
            matches!(&e, Error::Input(m) if m.contains("real.svg is a file, not a directory")),
            "{e}"
        );
        assert_eq!(
            files(&base),
            ["later.svg", "link.svg", "made.svg", "real.svg", "run"]
        );
        let _ = std::fs::remove_dir_all(&base);
    }
}

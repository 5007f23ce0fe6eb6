//! Where a command's outputs go: the one place that decides how a file is written, so nothing
//! the user has is lost and outputs land where the user points and nowhere else.
//!
//! A command declares its inputs and outputs in a [`Plan`] and calls [`Plan::check`] before it
//! does any work. The check refuses, naming both paths and the options they came from:
//! - an output that is one of the inputs: the same path, a symbolic link to it or a hard link
//!   to it (device + inode of existing files; for an output that does not exist yet, its
//!   canonical parent + name);
//! - two outputs of one run that are the same file, or a file inside a folder output;
//! - an input inside a folder output (the folder is replaced as a whole);
//! - an existing read-only file (replacing it by a rename would bypass the permission bit, even
//!   as root), a folder where a file is expected, a file where a folder is expected, a missing
//!   parent folder, a dangling symbolic link, a socket;
//! - an existing folder output that holds anything its kind of report does not write (only a
//!   previous report of the same kind, or an empty folder, is replaced).
//!
//! Then the checked [`Outputs`] write:
//! - a regular file (or a path that does not exist yet) through a temporary file in the same
//!   folder: write, fsync, rename over the target (a symbolic link is followed: the file it
//!   points to is replaced, the link stays); a dropped or failed [`Sink`] removes its temporary
//!   file and leaves the target untouched;
//! - a character or block device or a FIFO in place: opened for writing, never truncated,
//!   replaced, renamed over or deleted;
//! - `-`: standard output (single-file outputs only; a flag that prints to stdout claims it too,
//!   so two users of stdout collide like two outputs to one file);
//! - a folder: built in a temporary sibling ([`Staged`]) and moved into place by one rename; an
//!   existing folder is renamed aside, the new one renamed in, the old one deleted (if the
//!   second rename fails the old one is renamed back). A crash between the two renames leaves
//!   the old folder whole under `.NAME.old-PID`, never a mix of old and new files.
//!
//! What it cannot do: a process killed by SIGKILL leaves its temporary file or folder
//! (`.NAME.PID-N.tmp`) behind, and a path that changes between the check and the write is
//! written by the rules of what it was at the check.

use std::fmt;
use std::fs::{self, File, Metadata, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Component, Path, PathBuf};

/// Why an output was refused or could not be written. Every variant names the option and the
/// path; the data a user needs to fix the command line.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{out} would write over the input {input}{how}; nothing was written")]
    OverInput { out: Named, input: Named, how: &'static str },
    #[error("{a} and {b} are the same output{how}: give each its own path; nothing was written")]
    SameOutput { a: Named, b: Named, how: &'static str },
    #[error(
        "{inner} lies inside {dir}, which is replaced as a whole: choose a folder outside it; nothing was written"
    )]
    InsideFolder { inner: Named, dir: Named },
    #[error("{at}: {reason}; nothing was written")]
    Refused { at: Named, reason: String },
    #[error("{at}: cannot {action}: {err}")]
    Io { at: Named, action: &'static str, err: io::Error },
}

/// A path and the option it came from (empty for a library call without options).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Named {
    pub option: String,
    pub path: PathBuf,
}

impl fmt::Display for Named {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.option.is_empty() {
            write!(f, "{}", self.path.display())
        } else if self.path == Path::new(STDOUT) {
            write!(f, "{} (stdout)", self.option)
        } else {
            write!(f, "{} {}", self.option, self.path.display())
        }
    }
}

/// The path that means standard output.
pub const STDOUT: &str = "-";

/// What a folder output may replace: a `what` for messages ("an identification report") and
/// the names of the entries its kind of report writes.
#[derive(Clone, Copy, Debug)]
pub struct FolderKind {
    pub what: &'static str,
    pub owns: fn(&str) -> bool,
}

/// A checked single-file output, to pass back to [`Outputs::open`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileSlot(usize);

/// A checked folder output, to pass back to [`Outputs::stage`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FolderSlot(usize);

#[derive(Clone, Copy, Debug)]
enum Want {
    File,
    Folder(FolderKind),
    /// a flag that makes the command print machine output on stdout
    Stdout,
}

/// The inputs and outputs of one run, before the check.
#[derive(Debug, Default)]
pub struct Plan {
    inputs: Vec<Named>,
    outputs: Vec<(Named, Want)>,
}

impl Plan {
    pub fn new() -> Plan {
        Plan::default()
    }

    /// A file the run reads.
    pub fn input(&mut self, option: &str, path: &Path) -> &mut Plan {
        self.inputs.push(named(option, path));
        self
    }

    /// A single-file output; `-` is standard output.
    pub fn file(&mut self, option: &str, path: &Path) -> FileSlot {
        self.outputs.push((named(option, path), Want::File));
        FileSlot(self.outputs.len() - 1)
    }

    /// [`Plan::file`] for an optional output.
    pub fn file_opt(&mut self, option: &str, path: Option<&Path>) -> Option<FileSlot> {
        path.map(|p| self.file(option, p))
    }

    /// A folder output of `kind`, built aside and moved into place as a whole.
    pub fn folder(&mut self, option: &str, path: &Path, kind: FolderKind) -> FolderSlot {
        self.outputs.push((named(option, path), Want::Folder(kind)));
        FolderSlot(self.outputs.len() - 1)
    }

    /// [`Plan::folder`] for an optional output.
    pub fn folder_opt(&mut self, option: &str, path: Option<&Path>, kind: FolderKind) -> Option<FolderSlot> {
        path.map(|p| self.folder(option, p, kind))
    }

    /// The command prints machine output (a JSON summary) on stdout because of `option`.
    pub fn stdout(&mut self, option: &str) -> &mut Plan {
        self.outputs.push((named(option, Path::new(STDOUT)), Want::Stdout));
        self
    }

    /// Classifies every output and refuses collisions; nothing is written here.
    pub fn check(&self) -> Result<Outputs, OutputError> {
        let inputs: Vec<Where> = self.inputs.iter().map(|n| Where::of(n.clone())).collect();
        let mut targets = Vec::with_capacity(self.outputs.len());
        for (n, want) in &self.outputs {
            targets.push(Target::classify(n, *want)?);
        }
        for t in &targets {
            for i in &inputs {
                t.refuse_over_input(i)?;
            }
        }
        for (k, a) in targets.iter().enumerate() {
            for b in targets.iter().skip(k + 1) {
                a.refuse_same_output(b)?;
            }
        }
        Ok(Outputs { targets })
    }
}

fn named(option: &str, path: &Path) -> Named {
    Named { option: option.to_string(), path: path.to_path_buf() }
}

/// Where a path points: its canonical form (for a path that does not exist, the canonical
/// parent + name), the device and inode of an existing file, and whether it is a link.
#[derive(Clone, Debug)]
struct Where {
    named: Named,
    canon: PathBuf,
    id: Option<(u64, u64)>,
    link: bool,
}

impl Where {
    fn of(named: Named) -> Where {
        let p = &named.path;
        let link = fs::symlink_metadata(p).map(|m| m.file_type().is_symlink()).unwrap_or(false);
        let (canon, id) = match fs::metadata(p) {
            Ok(m) => (fs::canonicalize(p).unwrap_or_else(|_| absolute(p)), file_id(&m)),
            Err(_) => (canonical_new(p).unwrap_or_else(|| absolute(p)), None),
        };
        Where { named, canon, id, link }
    }

    /// Why `self` and `other` are one file, if they are.
    fn same_as(&self, other: &Where) -> Option<&'static str> {
        let same = match (self.id, other.id) {
            (Some(a), Some(b)) => a == b,
            _ => self.canon == other.canon,
        };
        if !same {
            return None;
        }
        Some(if self.link || other.link {
            " (through a symbolic link)"
        } else if self.canon != other.canon {
            " (a hard link to it)"
        } else {
            " (the same file)"
        })
    }
}

#[cfg(unix)]
fn file_id(m: &Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn file_id(_m: &Metadata) -> Option<(u64, u64)> {
    None
}

#[cfg(unix)]
fn mode(m: &Metadata) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    m.permissions().mode()
}

#[cfg(not(unix))]
fn mode(m: &Metadata) -> u32 {
    if m.permissions().readonly() {
        0o444
    } else {
        0o644
    }
}

/// No write bit for anyone: the owner said "do not write this", and a rename would not ask.
fn read_only(m: &Metadata) -> bool {
    mode(m) & 0o222 == 0
}

#[cfg(unix)]
fn special(m: &Metadata) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = m.file_type();
    if t.is_char_device() {
        Some("character device")
    } else if t.is_block_device() {
        Some("block device")
    } else if t.is_fifo() {
        Some("FIFO")
    } else if t.is_socket() {
        Some("socket")
    } else {
        None
    }
}

#[cfg(not(unix))]
fn special(_m: &Metadata) -> Option<&'static str> {
    None
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// The parent folder of `p` as a path to open (`.` for a bare name).
fn parent_of(p: &Path) -> &Path {
    p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// The last component of `p` if it is a plain name (not `..`, `.`, `/`).
fn plain_name(p: &Path) -> Option<&std::ffi::OsStr> {
    match p.components().next_back()? {
        Component::Normal(n) => Some(n),
        _ => None,
    }
}

/// Canonical parent + name of a path that does not exist (yet).
fn canonical_new(p: &Path) -> Option<PathBuf> {
    let name = plain_name(p)?;
    Some(fs::canonicalize(parent_of(p)).ok()?.join(name))
}

/// How a checked output is written.
#[derive(Clone, Debug)]
enum Dest {
    Stdout,
    /// a device or FIFO: written in place through the path as given
    InPlace(PathBuf),
    /// a regular file or a new path: temporary sibling + rename; `mode` of the file replaced
    Replace {
        path: PathBuf,
        mode: Option<u32>,
    },
    /// a folder: built aside, renamed into place
    Folder {
        path: PathBuf,
        kind: FolderKind,
    },
}

#[derive(Clone, Debug)]
struct Target {
    at: Where,
    dest: Dest,
    /// a flag's claim on stdout ([`Plan::stdout`]), not a file output
    flag: bool,
}

impl Target {
    fn classify(n: &Named, want: Want) -> Result<Target, OutputError> {
        let refuse = |reason: String| Err(OutputError::Refused { at: n.clone(), reason });
        let is_stdout = n.path == Path::new(STDOUT);
        match want {
            Want::Stdout => return Ok(Target { at: stdout_where(n), dest: Dest::Stdout, flag: true }),
            Want::File if is_stdout => return Ok(Target { at: stdout_where(n), dest: Dest::Stdout, flag: false }),
            Want::Folder(_) if is_stdout => return refuse("a folder cannot go to stdout".into()),
            _ => {}
        }
        if n.path.as_os_str().is_empty() {
            return refuse("empty path".into());
        }
        let at = Where::of(n.clone());
        let dest = match fs::symlink_metadata(&n.path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => Self::new_path(n, want)?,
            Err(e) => return Err(OutputError::Io { at: n.clone(), action: "inspect it", err: e }),
            Ok(lm) => match fs::metadata(&n.path) {
                Err(_) if lm.file_type().is_symlink() => {
                    return refuse("is a symbolic link to a file that does not exist".into())
                }
                Err(e) => return Err(OutputError::Io { at: n.clone(), action: "inspect it", err: e }),
                Ok(m) => Self::existing(n, want, &m, &at.canon)?,
            },
        };
        Ok(Target { at, dest, flag: false })
    }

    /// An output path that does not exist yet: its parent must be an existing folder.
    fn new_path(n: &Named, want: Want) -> Result<Dest, OutputError> {
        let refuse = |reason: String| Err(OutputError::Refused { at: n.clone(), reason });
        if plain_name(&n.path).is_none() {
            return refuse("does not end in a file name".into());
        }
        let parent = parent_of(&n.path);
        match fs::metadata(parent) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => return refuse(format!("{} is not a folder", parent.display())),
            Err(_) => return refuse(format!("the folder {} does not exist", parent.display())),
        }
        let Some(path) = canonical_new(&n.path) else {
            return refuse(format!("cannot resolve the folder {}", parent.display()));
        };
        Ok(match want {
            Want::Folder(kind) => Dest::Folder { path, kind },
            _ => Dest::Replace { path, mode: None },
        })
    }

    /// An output path that exists (symbolic links followed).
    fn existing(n: &Named, want: Want, m: &Metadata, canon: &Path) -> Result<Dest, OutputError> {
        let refuse = |reason: String| Err(OutputError::Refused { at: n.clone(), reason });
        if read_only(m) {
            return refuse(format!(
                "is read-only (mode {:o}): refused rather than replaced; make it writable or choose another path",
                mode(m) & 0o7777
            ));
        }
        match want {
            Want::Folder(kind) => {
                if !m.is_dir() {
                    return refuse(format!("exists and is not a folder ({} expected)", kind.what));
                }
                foreign_entry(&n.path, kind).map_err(|reason| OutputError::Refused { at: n.clone(), reason })?;
                Ok(Dest::Folder { path: canon.to_path_buf(), kind })
            }
            _ if m.is_dir() => refuse("is a folder (a file is expected here)".into()),
            _ => match special(m) {
                Some("socket") => refuse("is a socket, not a file".into()),
                Some(_) => Ok(Dest::InPlace(n.path.clone())),
                None => {
                    // The mode bits allow writing; check this user may (not root: EACCES).
                    if let Err(e) = OpenOptions::new().write(true).open(&n.path) {
                        if e.kind() == io::ErrorKind::PermissionDenied {
                            return refuse("is not writable by this user".into());
                        }
                    }
                    Ok(Dest::Replace { path: canon.to_path_buf(), mode: Some(mode(m)) })
                }
            },
        }
    }

    fn refuse_over_input(&self, input: &Where) -> Result<(), OutputError> {
        match &self.dest {
            Dest::Stdout => Ok(()),
            Dest::Folder { path, .. } => {
                if input.canon.starts_with(path) {
                    return Err(OutputError::InsideFolder { inner: input.named.clone(), dir: self.at.named.clone() });
                }
                Ok(())
            }
            _ => match self.at.same_as(input) {
                Some(how) => {
                    Err(OutputError::OverInput { out: self.at.named.clone(), input: input.named.clone(), how })
                }
                None => Ok(()),
            },
        }
    }

    fn refuse_same_output(&self, other: &Target) -> Result<(), OutputError> {
        let same = |how| Err(OutputError::SameOutput { a: self.at.named.clone(), b: other.at.named.clone(), how });
        match (&self.dest, &other.dest) {
            (Dest::Stdout, Dest::Stdout) => same(" (both write to stdout)"),
            (Dest::Stdout, _) | (_, Dest::Stdout) => Ok(()),
            (Dest::Folder { path: a, .. }, Dest::Folder { path: b, .. }) if a.starts_with(b) || b.starts_with(a) => {
                same(" (one folder holds the other)")
            }
            (Dest::Folder { path, .. }, _) if other.at.canon.starts_with(path) => {
                Err(OutputError::InsideFolder { inner: other.at.named.clone(), dir: self.at.named.clone() })
            }
            (_, Dest::Folder { path, .. }) if self.at.canon.starts_with(path) => {
                Err(OutputError::InsideFolder { inner: self.at.named.clone(), dir: other.at.named.clone() })
            }
            _ => match self.at.same_as(&other.at) {
                Some(how) => same(how),
                None => Ok(()),
            },
        }
    }
}

fn stdout_where(n: &Named) -> Where {
    Where { named: n.clone(), canon: PathBuf::from(STDOUT), id: None, link: false }
}

/// The first entry of the folder at `dir` that its kind does not write, as a reason to refuse.
fn foreign_entry(dir: &Path, kind: FolderKind) -> Result<(), String> {
    let entries = fs::read_dir(dir).map_err(|e| format!("cannot list it: {e}"))?;
    for e in entries {
        let e = e.map_err(|e| format!("cannot list it: {e}"))?;
        let name = e.file_name().to_string_lossy().into_owned();
        let is_file = e.file_type().map(|t| t.is_file()).unwrap_or(false);
        if !(is_file && (kind.owns)(&name)) {
            return Err(format!(
                "exists and holds `{name}`, which {} does not write: refused rather than replaced \
                 (only an empty folder or a previous report is replaced); move it away or choose another folder",
                kind.what
            ));
        }
    }
    Ok(())
}

/// The checked outputs of one run.
#[derive(Debug)]
pub struct Outputs {
    targets: Vec<Target>,
}

impl Outputs {
    /// Whether a file output (`-`) writes to stdout: human text then goes to stderr.
    pub fn stdout_taken(&self) -> bool {
        self.targets.iter().any(|t| matches!(t.dest, Dest::Stdout) && !t.flag)
    }

    /// Stdout for human-readable text (and for what a [`Plan::stdout`] flag prints), or
    /// stderr when a file output is `-`.
    pub fn human(&self) -> Box<dyn Write> {
        if self.stdout_taken() {
            Box::new(io::stderr())
        } else {
            Box::new(io::stdout())
        }
    }

    fn target(&self, i: usize) -> Result<&Target, OutputError> {
        self.targets.get(i).ok_or_else(|| OutputError::Refused {
            at: named("", Path::new("?")),
            reason: "an output that was not planned (a bug in the command)".into(),
        })
    }

    /// Opens a file output for writing; nothing is visible at the target until
    /// [`Sink::commit`] (devices, FIFOs and stdout receive the bytes as they come).
    pub fn open(&self, slot: FileSlot) -> Result<Sink, OutputError> {
        let t = self.target(slot.0)?;
        let at = t.at.named.clone();
        let io_err = |action, err| OutputError::Io { at: at.clone(), action, err };
        let inner = match &t.dest {
            Dest::Stdout => SinkKind::Stdout(BufWriter::new(io::stdout())),
            Dest::InPlace(p) => {
                let f = OpenOptions::new().write(true).open(p).map_err(|e| io_err("open it for writing", e))?;
                SinkKind::InPlace(BufWriter::new(f))
            }
            Dest::Replace { path, mode } => {
                let (tmp, f) = create_sibling(path).map_err(|e| io_err("create a temporary file beside it", e))?;
                let sink = SinkKind::Temp { w: BufWriter::new(f), tmp: tmp.clone(), dest: path.clone() };
                if let Some(m) = mode {
                    // the replacement keeps the permissions of the file it replaces
                    if let Err(e) = set_mode(&tmp, *m) {
                        let _ = fs::remove_file(&tmp);
                        return Err(io_err("copy the permissions", e));
                    }
                }
                sink
            }
            Dest::Folder { .. } => {
                return Err(OutputError::Refused { at, reason: "is a folder output, not a file".into() });
            }
        };
        Ok(Sink { at: t.at.named.clone(), inner: Some(inner) })
    }

    /// Writes `bytes` to a file output and commits it.
    pub fn write(&self, slot: FileSlot, bytes: &[u8]) -> Result<(), OutputError> {
        let mut s = self.open(slot)?;
        s.write_all(bytes).map_err(|e| OutputError::Io { at: s.at.clone(), action: "write it", err: e })?;
        s.commit()
    }

    /// A fresh temporary folder beside a folder output, to build the report in.
    pub fn stage(&self, slot: FolderSlot) -> Result<Staged, OutputError> {
        let t = self.target(slot.0)?;
        let at = t.at.named.clone();
        let Dest::Folder { path, kind } = &t.dest else {
            return Err(OutputError::Refused { at, reason: "is a file output, not a folder".into() });
        };
        let tmp = create_sibling_dir(path).map_err(|e| OutputError::Io {
            at: at.clone(),
            action: "create a temporary folder beside it",
            err: e,
        })?;
        Ok(Staged { at, tmp: Some(tmp), dest: path.clone(), kind: *kind })
    }
}

/// Writes one file by the rules above, with no inputs to compare against (library use).
pub fn write_file(path: &Path, body: impl FnOnce(&mut Sink) -> io::Result<()>) -> Result<(), OutputError> {
    let mut plan = Plan::new();
    let slot = plan.file("", path);
    let outs = plan.check()?;
    let mut s = outs.open(slot)?;
    body(&mut s).map_err(|e| OutputError::Io { at: s.at.clone(), action: "write it", err: e })?;
    s.commit()
}

#[cfg(unix)]
fn set_mode(p: &Path, mode: u32) -> io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(p, fs::Permissions::from_mode(mode & 0o777))
}

#[cfg(not(unix))]
fn set_mode(_p: &Path, _mode: u32) -> io::Result<()> {
    Ok(())
}

/// `.NAME.PID-N.tmp` beside `dest` (created exclusively, so it never replaces anything).
fn sibling_names(dest: &Path, what: &'static str) -> impl Iterator<Item = PathBuf> {
    let dir = parent_of(dest).to_path_buf();
    let name = dest.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let pid = std::process::id();
    (0..1000).map(move |k| dir.join(format!(".{name}.{pid}-{k}.{what}")))
}

fn create_sibling(dest: &Path) -> io::Result<(PathBuf, File)> {
    let mut last = io::Error::new(io::ErrorKind::AlreadyExists, "no free temporary name");
    for tmp in sibling_names(dest, "tmp") {
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = e,
            Err(e) => return Err(e),
        }
    }
    Err(last)
}

fn create_sibling_dir(dest: &Path) -> io::Result<PathBuf> {
    let mut last = io::Error::new(io::ErrorKind::AlreadyExists, "no free temporary name");
    for tmp in sibling_names(dest, "tmp") {
        match fs::create_dir(&tmp) {
            Ok(()) => return Ok(tmp),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = e,
            Err(e) => return Err(e),
        }
    }
    Err(last)
}

/// Durability of a rename: the folder entry itself is on disk (best effort: not every
/// filesystem lets a folder be opened and synced).
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

enum SinkKind {
    Stdout(BufWriter<io::Stdout>),
    InPlace(BufWriter<File>),
    Temp { w: BufWriter<File>, tmp: PathBuf, dest: PathBuf },
}

/// An open file output. Dropped without [`Sink::commit`] (an error, a `?`), its temporary file
/// is removed and the target was never touched.
pub struct Sink {
    at: Named,
    inner: Option<SinkKind>,
}

impl Sink {
    /// Flushes; for a regular file: fsync, rename over the target, fsync the folder.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let at = self.at.clone();
        let io_err = |action, err| OutputError::Io { at: at.clone(), action, err };
        match self.inner.take() {
            None => Ok(()),
            Some(SinkKind::Stdout(mut w)) => w.flush().map_err(|e| io_err("write to stdout", e)),
            Some(SinkKind::InPlace(mut w)) => w.flush().map_err(|e| io_err("write it", e)),
            Some(SinkKind::Temp { w, tmp, dest }) => {
                let done = (|| {
                    let f = w.into_inner().map_err(|e| ("write it", e.into_error()))?;
                    f.sync_all().map_err(|e| ("write it to disk", e))?;
                    fs::rename(&tmp, &dest).map_err(|e| ("move the temporary file into place", e))
                })();
                match done {
                    Ok(()) => {
                        sync_dir(parent_of(&dest));
                        Ok(())
                    }
                    Err((action, e)) => {
                        let _ = fs::remove_file(&tmp);
                        Err(io_err(action, e))
                    }
                }
            }
        }
    }

    /// The output as the user named it.
    pub fn named(&self) -> &Named {
        &self.at
    }

    fn writer(&mut self) -> io::Result<&mut dyn Write> {
        match self.inner.as_mut() {
            Some(SinkKind::Stdout(w)) => Ok(w),
            Some(SinkKind::InPlace(w)) => Ok(w),
            Some(SinkKind::Temp { w, .. }) => Ok(w),
            None => Err(io::Error::other("output already committed")),
        }
    }
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for Sink {
    fn drop(&mut self) {
        if let Some(SinkKind::Temp { w, tmp, .. }) = self.inner.take() {
            // into_parts: drop the buffer without flushing it into a file about to go
            drop(w.into_parts());
            let _ = fs::remove_file(tmp);
        }
    }
}

/// A folder output being built. Dropped without [`Staged::commit`], the temporary folder is
/// removed with everything in it; the target was never touched.
pub struct Staged {
    at: Named,
    tmp: Option<PathBuf>,
    dest: PathBuf,
    kind: FolderKind,
}

impl Staged {
    /// The output as the user named it.
    pub fn named(&self) -> &Named {
        &self.at
    }

    /// Where to write the report's files.
    pub fn path(&self) -> &Path {
        self.tmp.as_deref().unwrap_or(&self.dest)
    }

    /// Moves the built folder into place (see the module documentation for what an existing
    /// folder goes through).
    pub fn commit(mut self) -> Result<(), OutputError> {
        let Some(tmp) = self.tmp.take() else { return Ok(()) };
        let result = self.swap_in(&tmp);
        if result.is_err() {
            let _ = fs::remove_dir_all(&tmp);
        }
        result
    }

    fn swap_in(&self, tmp: &Path) -> Result<(), OutputError> {
        let io_err = |action, err| OutputError::Io { at: self.at.clone(), action, err };
        sync_files(tmp).map_err(|e| io_err("write the report to disk", e))?;
        match fs::symlink_metadata(&self.dest) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                fs::rename(tmp, &self.dest).map_err(|e| io_err("move the new folder into place", e))?;
            }
            Err(e) => return Err(io_err("inspect it", e)),
            Ok(_) => {
                // Checked again: a file may have been put there while the report was built.
                foreign_entry(&self.dest, self.kind)
                    .map_err(|reason| OutputError::Refused { at: self.at.clone(), reason })?;
                let old = sibling_names(&self.dest, "old")
                    .find(|p| fs::symlink_metadata(p).is_err())
                    .ok_or_else(|| io_err("name the old folder", io::Error::other("no free name")))?;
                fs::rename(&self.dest, &old).map_err(|e| io_err("move the old folder aside", e))?;
                if let Err(e) = fs::rename(tmp, &self.dest) {
                    let _ = fs::rename(&old, &self.dest);
                    return Err(io_err("move the new folder into place", e));
                }
                let _ = fs::remove_dir_all(&old);
            }
        }
        sync_dir(parent_of(&self.dest));
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            let _ = fs::remove_dir_all(tmp);
        }
    }
}

/// fsync every file in `dir` (the report's files are written by plain `fs::write`).
fn sync_files(dir: &Path) -> io::Result<()> {
    for e in fs::read_dir(dir)? {
        let e = e?;
        if e.file_type()?.is_file() {
            File::open(e.path())?.sync_all()?;
        }
    }
    sync_dir(dir);
    Ok(())
}

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};

    const REPORT: FolderKind = FolderKind { what: "a test report", owns: |n| n == "a.txt" || n == "b.txt" };

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        v.sort();
        v
    }

    fn write_one(opt: &str, path: &Path, text: &str) -> Result<(), OutputError> {
        let mut plan = Plan::new();
        let s = plan.file(opt, path);
        plan.check()?.write(s, text.as_bytes())
    }

    #[test]
    fn a_new_file_is_written_whole_and_no_temporary_file_stays() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.csv");
        write_one("--out", &p, "t,q\n0,0\n").unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "t,q\n0,0\n");
        assert_eq!(entries(d.path()), ["out.csv"]);
    }

    #[test]
    fn a_replaced_file_keeps_its_permissions() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.toml");
        fs::write(&p, "old").unwrap();
        fs::set_permissions(&p, fs::Permissions::from_mode(0o600)).unwrap();
        write_one("--out", &p, "new").unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "new");
        assert_eq!(fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o600);
    }

    #[test]
    fn a_dropped_sink_leaves_the_target_untouched_and_no_temporary_file() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.csv");
        fs::write(&p, "before").unwrap();
        let mut plan = Plan::new();
        let s = plan.file("--out", &p);
        let outs = plan.check().unwrap();
        let mut sink = outs.open(s).unwrap();
        sink.write_all(b"half of a log").unwrap();
        assert_eq!(entries(d.path()).len(), 2, "the temporary file sits beside the target while writing");
        drop(sink);
        assert_eq!(fs::read_to_string(&p).unwrap(), "before");
        assert_eq!(entries(d.path()), ["out.csv"]);
    }

    #[test]
    fn a_failing_body_leaves_nothing() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("new.csv");
        let r = write_file(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("injected"))
        });
        let e = r.unwrap_err().to_string();
        assert!(e.contains("injected") && e.contains("new.csv"), "{e}");
        assert!(entries(d.path()).is_empty());
    }

    fn over_input(out: &Path, input: &Path) -> String {
        let mut plan = Plan::new();
        plan.input("--log", input);
        plan.file("--emit-model", out);
        plan.check().unwrap_err().to_string()
    }

    #[test]
    fn an_output_onto_an_input_is_refused_by_path_symlink_and_hard_link() {
        let d = tempfile::tempdir().unwrap();
        let log = d.path().join("run.csv");
        fs::write(&log, "t,q\n").unwrap();
        let e = over_input(&log, &log);
        assert!(e.contains("--emit-model") && e.contains("--log") && e.contains("run.csv"), "{e}");
        assert!(e.contains("the same file"), "{e}");
        // the same file by another spelling
        let e = over_input(&d.path().join(".").join("run.csv"), &log);
        assert!(e.contains("the same file"), "{e}");
        let link = d.path().join("link.csv");
        std::os::unix::fs::symlink(&log, &link).unwrap();
        assert!(over_input(&link, &log).contains("symbolic link"));
        assert!(over_input(&log, &link).contains("symbolic link"));
        let hard = d.path().join("hard.csv");
        fs::hard_link(&log, &hard).unwrap();
        let e = over_input(&hard, &log);
        assert!(e.contains("hard link") && e.contains("hard.csv") && e.contains("run.csv"), "{e}");
        assert_eq!(fs::read_to_string(&log).unwrap(), "t,q\n");
    }

    #[test]
    fn a_new_output_is_compared_by_canonical_parent_and_name() {
        let d = tempfile::tempdir().unwrap();
        fs::create_dir(d.path().join("sub")).unwrap();
        let mut plan = Plan::new();
        plan.file("--json", &d.path().join("sub/../x.json"));
        plan.file("--report", &d.path().join("x.json"));
        let e = plan.check().unwrap_err().to_string();
        assert!(e.contains("--json") && e.contains("--report") && e.contains("same output"), "{e}");
    }

    #[test]
    fn two_users_of_stdout_collide() {
        let mut plan = Plan::new();
        plan.file("--out", Path::new("-"));
        plan.stdout("--json");
        let e = plan.check().unwrap_err().to_string();
        assert!(e.contains("--out (stdout)") && e.contains("--json (stdout)"), "{e}");
        let mut plan = Plan::new();
        plan.file("--out", Path::new("-"));
        assert!(plan.check().unwrap().stdout_taken());
        let mut plan = Plan::new();
        plan.stdout("--json");
        assert!(!plan.check().unwrap().stdout_taken(), "a flag's own output is not redirected");
    }

    #[test]
    fn read_only_files_folders_and_missing_parents_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let ro = d.path().join("ro.toml");
        fs::write(&ro, "keep").unwrap();
        fs::set_permissions(&ro, fs::Permissions::from_mode(0o444)).unwrap();
        let e = write_one("--out", &ro, "x").unwrap_err().to_string();
        assert!(e.contains("read-only") && e.contains("ro.toml"), "{e}");
        assert_eq!(fs::read_to_string(&ro).unwrap(), "keep");
        let e = write_one("--out", d.path(), "x").unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        let e = write_one("--out", &d.path().join("no/such/x.csv"), "x").unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
        let dangling = d.path().join("dangling");
        std::os::unix::fs::symlink(d.path().join("nothing"), &dangling).unwrap();
        let e = write_one("--out", &dangling, "x").unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        assert!(fs::symlink_metadata(&dangling).unwrap().file_type().is_symlink());
    }

    #[test]
    fn a_symlinked_output_replaces_the_file_and_keeps_the_link() {
        let d = tempfile::tempdir().unwrap();
        let real = d.path().join("real.toml");
        fs::write(&real, "old").unwrap();
        let link = d.path().join("link.toml");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_one("--out", &link, "new").unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(fs::read_to_string(&real).unwrap(), "new");
    }

    #[test]
    fn dev_null_is_written_in_place() {
        write_one("--out", Path::new("/dev/null"), "discarded").unwrap();
        assert!(fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    }

    #[test]
    fn a_folder_is_created_replaced_or_refused_as_a_whole() {
        let d = tempfile::tempdir().unwrap();
        let rep = d.path().join("rep");
        let build = |files: &[&str]| -> Result<(), OutputError> {
            let mut plan = Plan::new();
            let s = plan.folder("--report", &rep, REPORT);
            let st = plan.check()?.stage(s)?;
            for f in files {
                fs::write(st.path().join(f), f).unwrap();
            }
            st.commit()
        };
        build(&["a.txt", "b.txt"]).unwrap();
        assert_eq!(entries(&rep), ["a.txt", "b.txt"]);
        // a previous report is replaced as a whole: b.txt does not survive from the old one
        build(&["a.txt"]).unwrap();
        assert_eq!(entries(&rep), ["a.txt"]);
        assert_eq!(entries(d.path()), ["rep"]);
        // a folder holding anything else is refused and kept
        fs::write(rep.join("notes.md"), "mine").unwrap();
        let e = build(&["a.txt"]).unwrap_err().to_string();
        assert!(e.contains("notes.md") && e.contains("--report"), "{e}");
        assert_eq!(entries(&rep), ["a.txt", "notes.md"]);
        assert_eq!(entries(d.path()), ["rep"]);
    }

    #[test]
    fn a_dropped_staging_folder_leaves_the_old_report() {
        let d = tempfile::tempdir().unwrap();
        let rep = d.path().join("rep");
        fs::create_dir(&rep).unwrap();
        fs::write(rep.join("a.txt"), "old").unwrap();
        let mut plan = Plan::new();
        let s = plan.folder("--report", &rep, REPORT);
        let st = plan.check().unwrap().stage(s).unwrap();
        fs::write(st.path().join("a.txt"), "new").unwrap();
        drop(st);
        assert_eq!(fs::read_to_string(rep.join("a.txt")).unwrap(), "old");
        assert_eq!(entries(d.path()), ["rep"]);
    }

    #[test]
    fn inputs_and_outputs_inside_a_folder_output_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let rep = d.path().join("rep");
        fs::create_dir(&rep).unwrap();
        fs::write(rep.join("a.txt"), "log").unwrap();
        let mut plan = Plan::new();
        plan.input("--log", &rep.join("a.txt"));
        plan.folder("--report", &rep, REPORT);
        let e = plan.check().unwrap_err().to_string();
        assert!(e.contains("--log") && e.contains("inside --report"), "{e}");
        let mut plan = Plan::new();
        plan.folder("--report", &rep, REPORT);
        plan.file("--out", &rep.join("m.toml"));
        let e = plan.check().unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("inside --report"), "{e}");
        let mut plan = Plan::new();
        plan.folder("--report", Path::new("-"), REPORT);
        assert!(plan.check().unwrap_err().to_string().contains("stdout"));
        // a file where a folder is expected
        let mut plan = Plan::new();
        plan.folder("--report", &rep.join("a.txt"), REPORT);
        assert!(plan.check().unwrap_err().to_string().contains("not a folder"));
    }
}

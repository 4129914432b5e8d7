//! Reading the log's files as streams: one bounded line at a time, every
//! problem named by file, line and column.
//!
//! The files are plain comma-separated text (no quoting beyond a pair of
//! double quotes around a whole field, as spreadsheets write them), so the
//! reader splits lines itself and never holds more than one line: a file of
//! any size, or of binary garbage, costs the same memory.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::format::Meta;

/// Longest line accepted, bytes: a row of this format is well under 200.
pub const MAX_LINE_BYTES: usize = 4096;

/// Files larger than this get a progress bar (when stderr is a terminal).
const PROGRESS_FROM_BYTES: u64 = 50 << 20;

/// What is wrong with a file; the text names the file, the line and, when
/// one column is at fault, the column (1-based) and its name.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file cannot be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The command line asks for what the files cannot give.
    #[error("{0}")]
    Usage(String),
    /// A line does not say what the format needs.
    #[error("{}:{line}:{}{message}", path.display(), column.as_ref().map(|(k, n)| format!("{k}: column `{n}`: ")).unwrap_or_else(|| " ".into()))]
    Bad {
        /// The file.
        path: PathBuf,
        /// Line, 1-based.
        line: u64,
        /// Column number (1-based) and name, when one is at fault.
        column: Option<(usize, String)>,
        /// What is wrong, in words.
        message: String,
    },
}

/// A file of the log, read line by line.
pub struct LineFile {
    path: PathBuf,
    reader: BufReader<Box<dyn Read>>,
    line: u64,
    buf: Vec<u8>,
    /// The `# key: value` lines before the header.
    pub meta: Meta,
    header: Vec<String>,
    pending: Option<Vec<u8>>,
    progress: Option<ProgressBar>,
}

/// Counts the bytes read for the progress bar, and clears the bar at the
/// end of the file.
pub(crate) struct Counting<R> {
    inner: R,
    bar: Option<ProgressBar>,
}

impl<R> Counting<R> {
    /// `inner`, advancing `bar` (when there is one) as it is read.
    pub(crate) fn new(inner: R, bar: Option<ProgressBar>) -> Self {
        Self { inner, bar }
    }
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(b) = &self.bar {
            if n == 0 && !buf.is_empty() {
                b.finish_and_clear();
            } else {
                b.inc(n as u64);
            }
        }
        Ok(n)
    }
}

/// A progress bar for a file of `len` bytes, when `wanted` and the file
/// is large enough to wait for (drawn only on a terminal).
pub(crate) fn progress_for(wanted: bool, len: u64, path: &Path) -> Option<ProgressBar> {
    (wanted && len >= PROGRESS_FROM_BYTES).then(|| progress_bar(len, path))
}

impl LineFile {
    /// Opens `path`, reads its `#` lines and its header.
    pub fn open(path: &Path) -> Result<Self, LogError> {
        let io = |source| LogError::Io {
            path: path.to_owned(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let bar = (len >= PROGRESS_FROM_BYTES).then(|| progress_bar(len, path));
        let boxed: Box<dyn Read> = Box::new(Counting {
            inner: file,
            bar: bar.clone(),
        });
        let mut f = Self {
            path: path.to_owned(),
            reader: BufReader::new(boxed),
            line: 0,
            buf: Vec::with_capacity(256),
            meta: Meta::default(),
            header: Vec::new(),
            pending: None,
            progress: bar,
        };
        loop {
            let Some(raw) = f.raw_line()? else {
                return Err(f.bad(None, "the file has no header line".into()));
            };
            let text = f.text(&raw)?.trim().to_owned();
            if let Some(rest) = text.strip_prefix('#') {
                f.meta_line(rest)?;
                continue;
            }
            if text.is_empty() {
                continue;
            }
            f.header = split(&text).into_iter().map(str::to_owned).collect();
            break;
        }
        Ok(f)
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Line of the last line read.
    pub fn line(&self) -> u64 {
        self.line
    }

    /// Position of `name` in the header.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Position of `name`, which the format needs.
    pub fn required(&self, name: &str) -> Result<usize, LogError> {
        self.column(name).ok_or_else(|| LogError::Bad {
            path: self.path.clone(),
            line: self.header_line(),
            column: None,
            message: format!(
                "column `{name}` is missing from the header (it has: {})",
                self.header.join(",")
            ),
        })
    }

    fn header_line(&self) -> u64 {
        self.line
    }

    /// The fields of the next data line (blank lines and `#` lines
    /// skipped), `None` at the end of the file.
    pub fn next_fields(&mut self) -> Result<Option<Vec<String>>, LogError> {
        loop {
            let raw = match self.pending.take() {
                Some(r) => r,
                None => match self.raw_line()? {
                    Some(r) => r,
                    None => {
                        if let Some(b) = &self.progress {
                            b.finish_and_clear();
                        }
                        return Ok(None);
                    }
                },
            };
            let text = self.text(&raw)?.trim();
            if text.is_empty() || text.starts_with('#') {
                continue;
            }
            let fields: Vec<String> = split(text).into_iter().map(str::to_owned).collect();
            if fields.len() > self.header.len() {
                return Err(self.bad(
                    None,
                    format!(
                        "{} fields, the header has {}",
                        fields.len(),
                        self.header.len()
                    ),
                ));
            }
            return Ok(Some(fields));
        }
    }

    /// One line's bytes, without its end, at most [`MAX_LINE_BYTES`].
    fn raw_line(&mut self) -> Result<Option<Vec<u8>>, LogError> {
        self.buf.clear();
        let limit = (MAX_LINE_BYTES + 1) as u64;
        let n = (&mut self.reader)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(|source| LogError::Io {
                path: self.path.clone(),
                source,
            })?;
        if n == 0 {
            return Ok(None);
        }
        self.line += 1;
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
        } else if self.buf.len() > MAX_LINE_BYTES {
            return Err(self.bad(
                None,
                format!(
                    "the line is longer than {MAX_LINE_BYTES} bytes: not a file of this format"
                ),
            ));
        }
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        Ok(Some(std::mem::take(&mut self.buf)))
    }

    fn text<'a>(&self, raw: &'a [u8]) -> Result<&'a str, LogError> {
        std::str::from_utf8(raw).map_err(|e| {
            let at = e.valid_up_to();
            let column = raw[..at].iter().filter(|&&b| b == b',').count() + 1;
            LogError::Bad {
                path: self.path.clone(),
                line: self.line,
                column: Some((column, self.name_of(column - 1))),
                message: format!(
                    "byte {} is not UTF-8 text: not a file of this format",
                    at + 1
                ),
            }
        })
    }

    fn meta_line(&mut self, rest: &str) -> Result<(), LogError> {
        let Some((key, value)) = rest.split_once(':') else {
            return Ok(());
        };
        let value = value.trim();
        match key.trim() {
            "format" => self.meta.format = Some(value.to_owned()),
            "clock" => self.meta.clock = Some(value.to_owned()),
            "propagation_speed_m_s" => match value.parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => self.meta.propagation_speed_m_s = Some(v),
                _ => {
                    return Err(self.bad(
                        None,
                        format!("propagation_speed_m_s `{value}` is not a positive number"),
                    ));
                }
            },
            "mobile_height_m" => match value.parse::<f64>() {
                Ok(v) if v.is_finite() && v.abs() <= 100_000.0 => {
                    self.meta.mobile_height_m = Some(v);
                }
                _ => {
                    return Err(self.bad(
                        None,
                        format!("mobile_height_m `{value}` is not a height in metres"),
                    ));
                }
            },
            // Other keys are the writer's notes.
            _ => {}
        }
        Ok(())
    }

    fn name_of(&self, k: usize) -> String {
        self.header
            .get(k)
            .cloned()
            .unwrap_or_else(|| "(beyond the header)".into())
    }

    /// An error at the current line, in column `k` (0-based) when given.
    pub fn bad(&self, k: Option<usize>, message: String) -> LogError {
        LogError::Bad {
            path: self.path.clone(),
            line: self.line,
            column: k.map(|k| (k + 1, self.name_of(k))),
            message,
        }
    }

    /// Field `k`, trimmed; empty when the line is short.
    pub fn field<'a>(&self, f: &'a [String], k: usize) -> &'a str {
        f.get(k).map_or("", |s| s.as_str())
    }

    /// Field `k`, which must not be blank.
    pub fn present<'a>(&self, f: &'a [String], k: usize) -> Result<&'a str, LogError> {
        match self.field(f, k) {
            "" => Err(self.bad(Some(k), "is blank".into())),
            v => Ok(v),
        }
    }

    /// Field `k` as a finite number.
    pub fn number(&self, f: &[String], k: usize) -> Result<f64, LogError> {
        let v = self.present(f, k)?;
        match v.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(_) => Err(self.bad(Some(k), format!("`{v}` is not a finite number"))),
            Err(_) => Err(self.bad(Some(k), format!("`{v}` is not a number"))),
        }
    }

    /// Field `k` as a number when not blank.
    pub fn optional_number(&self, f: &[String], k: Option<usize>) -> Result<Option<f64>, LogError> {
        match k {
            Some(k) if !self.field(f, k).is_empty() => self.number(f, k).map(Some),
            _ => Ok(None),
        }
    }
}

fn progress_bar(len: u64, path: &Path) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("{elapsed:>4} [{bar:40}] {bytes}/{total_bytes} {msg}")
    {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(path.display().to_string());
    pb
}

/// Splits a line at commas, dropping the double quotes around a field.
fn split(line: &str) -> Vec<&str> {
    line.split(',')
        .map(|f| {
            let f = f.trim();
            f.strip_prefix('"')
                .and_then(|g| g.strip_suffix('"'))
                .unwrap_or(f)
                .trim()
        })
        .collect()
}

//! A reader that refuses lines longer than any of the format's: the CSV
//! reader buffers a whole record, so an endless line (`/dev/zero`, a
//! binary file without line ends) would otherwise grow without bound.

use std::io::{Error, ErrorKind, Read};

/// Longest line taken, bytes: a UTIL row of the 27-column layout is about
/// 250 bytes, so this is far beyond any real one (the arrival-time log's
/// limit too).
pub const MAX_LINE_BYTES: u64 = crate::tdoa_log::read::MAX_LINE_BYTES as u64;

/// `inner`, failing once a line runs past [`MAX_LINE_BYTES`].
pub struct LineLimit<R> {
    inner: R,
    /// Bytes of the current line so far.
    run: u64,
    /// The current line's number, from 1.
    line: u64,
}

impl<R> LineLimit<R> {
    /// Limits the lines of `inner`.
    pub fn new(inner: R) -> Self {
        Self {
            inner,
            run: 0,
            line: 1,
        }
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for &b in &buf[..n] {
            if b == b'\n' {
                self.run = 0;
                self.line += 1;
            } else {
                self.run += 1;
                if self.run > MAX_LINE_BYTES {
                    return Err(Error::new(
                        ErrorKind::InvalidData,
                        format!(
                            "line {} is longer than {MAX_LINE_BYTES} bytes: not a CSV file of this format",
                            self.line
                        ),
                    ));
                }
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_line_is_refused_and_short_lines_pass() {
        let mut ok = String::new();
        LineLimit::new("a,b\n1,2\n".as_bytes())
            .read_to_string(&mut ok)
            .unwrap();
        assert_eq!(ok, "a,b\n1,2\n");
        let mut sink = Vec::new();
        let e = LineLimit::new(std::io::repeat(0).take(1 << 20))
            .read_to_end(&mut sink)
            .unwrap_err();
        assert!(e.to_string().contains("line 1 is longer than"), "{e}");
    }
}

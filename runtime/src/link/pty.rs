//! Pseudo-terminal pairs: a serial port without hardware. The slave end
//! has a path (`/dev/pts/N`) that a host opens as it would a USB adapter;
//! whoever holds the [`Pty`] plays the device on the master end. Used by
//! the emulated boards and by tests, so that no device and no system
//! package (`socat`) is needed.

use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::time::Duration;

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};

/// A pseudo-terminal pair; the device's end, with the path of the host's.
pub struct Pty {
    master: File,
    /// Held open so that the master end never reads a hang-up while no
    /// host has the path open (between a host's reconnections).
    _slave: OwnedFd,
    path: PathBuf,
}

impl Pty {
    /// A new pair, in raw mode (no echo, no line editing: bytes pass as they are).
    pub fn open() -> io::Result<Self> {
        let pair = nix::pty::openpty(None, None).map_err(io::Error::from)?;
        let path = nix::unistd::ttyname(pair.slave.as_fd()).map_err(io::Error::from)?;
        let mut raw = tcgetattr(pair.slave.as_fd()).map_err(io::Error::from)?;
        cfmakeraw(&mut raw);
        tcsetattr(pair.slave.as_fd(), SetArg::TCSANOW, &raw).map_err(io::Error::from)?;
        Ok(Self {
            master: File::from(pair.master),
            _slave: pair.slave,
            path,
        })
    }

    /// The path a host opens (`serial:PATH`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The device's end, as a reader whose reads give up after `timeout`
    /// (an error of kind `TimedOut`) and a writer.
    pub fn device_end(&self, timeout: Duration) -> io::Result<(PtyReader, File)> {
        Ok((
            PtyReader {
                master: self.master.try_clone()?,
                timeout,
            },
            self.master.try_clone()?,
        ))
    }
}

/// The master end of a [`Pty`] read with a timeout.
pub struct PtyReader {
    master: File,
    timeout: Duration,
}

impl Read for PtyReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let ms = u16::try_from(self.timeout.as_millis()).unwrap_or(u16::MAX);
        let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLIN)];
        match poll(&mut fds, PollTimeout::from(ms)) {
            Ok(0) => Err(io::Error::new(io::ErrorKind::TimedOut, "no bytes")),
            Ok(_) => self.master.read(buf),
            Err(nix::errno::Errno::EINTR) => Err(io::ErrorKind::Interrupted.into()),
            Err(e) => Err(e.into()),
        }
    }
}

/// Writes `bytes` to the device's end (a convenience of tests).
pub fn write_all(writer: &mut File, bytes: &[u8]) -> io::Result<()> {
    writer.write_all(bytes)?;
    writer.flush()
}

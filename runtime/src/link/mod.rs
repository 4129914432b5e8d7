//! Byte-stream links to devices (a transmitter board, a receiver ring, any
//! serial or networked sensor), independent of what the bytes mean:
//!
//! - [`address`]: `serial:PATH[@BAUD]` and `tcp:HOST:PORT`;
//! - [`Link`]: a connection kept open by a thread of its own, which
//!   reconnects with back-off when the device goes away (a cable pulled, a
//!   board restarted, a bridge rebooted) and says so, and hands every chunk
//!   of bytes and every change of state to the sink it was opened with;
//! - [`pty`]: pseudo-terminal pairs, for emulated boards and for tests
//!   that need a serial port without hardware.
//!
//! Serial ports go through the `serialport` crate built without libudev, so
//! a fresh machine needs no system package.

pub mod address;
pub mod pty;

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub use address::{AddressError, DEFAULT_BAUD, LinkAddress};

/// How long a read waits before the link thread looks whether it must stop.
const READ_POLL: Duration = Duration::from_millis(50);

/// How long a TCP connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// How long a write may block (a serial line at 9600 baud sends a 256-byte
/// frame in 0.27 s).
const WRITE_TIMEOUT: Duration = Duration::from_millis(500);

/// Bytes read at most at once.
const READ_CHUNK: usize = 4096;

/// Waits between reconnection attempts: from `first`, doubling, up to `max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    /// The first wait after a failure.
    pub first: Duration,
    /// The longest wait.
    pub max: Duration,
}

impl Default for Backoff {
    /// 100 ms, doubling to 5 s: a board that restarts (about a second) is
    /// back within a few hundred milliseconds of it, and a device that is
    /// gone for good costs one attempt (and at most one log line) every 5 s.
    fn default() -> Self {
        Self {
            first: Duration::from_millis(100),
            max: Duration::from_secs(5),
        }
    }
}

/// Whether a link is usable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkState {
    /// Opening (first attempt, or after a wait).
    Connecting,
    /// Open: bytes flow.
    Up,
    /// Not open; waiting before the next attempt.
    Down,
}

impl LinkState {
    /// A word for logs and tables.
    pub fn name(self) -> &'static str {
        match self {
            LinkState::Connecting => "connecting",
            LinkState::Up => "up",
            LinkState::Down => "down",
        }
    }
}

/// A link's state and counters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkStatus {
    /// The device's address.
    pub address: String,
    /// Whether it is usable.
    pub state: LinkState,
    /// Times it was opened.
    pub connects: u64,
    /// Bytes read.
    pub bytes_in: u64,
    /// Bytes written.
    pub bytes_out: u64,
    /// Why it was last lost or could not be opened.
    pub last_error: Option<String>,
}

impl LinkStatus {
    /// The link in words for an operator's line: `on ADDRESS: link STATE`,
    /// the reconnects, and while it is not up why it was lost.
    pub fn describe(&self) -> String {
        let mut out = format!("on {}: link {}", self.address, self.state.name());
        if self.connects > 1 {
            out.push_str(&format!(" ({} reconnects)", self.connects - 1));
        }
        if let Some(e) = self
            .last_error
            .as_ref()
            .filter(|_| self.state != LinkState::Up)
        {
            out.push_str(&format!(" ({e})"));
        }
        out
    }
}

/// What a link hands to its sink, in order, from its own thread.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkEvent {
    /// Opened (again): a protocol starts its handshake.
    Connected,
    /// A chunk of bytes as read.
    Bytes(Vec<u8>),
    /// Lost, with why; the link tries again after its back-off.
    Disconnected(String),
}

/// Why bytes could not be sent.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The link is not open now.
    #[error("{0}: not connected")]
    NotConnected(String),
    /// The write failed (the link is then reopened).
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
}

type Writer = Box<dyn Write + Send>;

/// The state a link's thread shares with its handle.
struct Shared {
    address: LinkAddress,
    writer: Mutex<Option<Writer>>,
    status: Mutex<LinkStatus>,
    stop: AtomicBool,
}

impl Shared {
    fn status(&self) -> std::sync::MutexGuard<'_, LinkStatus> {
        self.status.lock().unwrap_or_else(PoisonError::into_inner)
    }
    fn writer(&self) -> std::sync::MutexGuard<'_, Option<Writer>> {
        self.writer.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A device link kept open by its own thread. Dropping it closes the
/// connection and stops the thread.
pub struct Link {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Link {
    /// Opens `address` (at once, and again with `backoff` whenever it is
    /// lost), handing what happens to `sink` from the link's thread.
    pub fn open(
        address: LinkAddress,
        backoff: Backoff,
        sink: impl FnMut(LinkEvent) + Send + 'static,
    ) -> Self {
        let shared = Arc::new(Shared {
            status: Mutex::new(LinkStatus {
                address: address.to_string(),
                state: LinkState::Connecting,
                connects: 0,
                bytes_in: 0,
                bytes_out: 0,
                last_error: None,
            }),
            address,
            writer: Mutex::new(None),
            stop: AtomicBool::new(false),
        });
        let thread_shared = shared.clone();
        let thread = std::thread::Builder::new()
            .name("device-link".into())
            .spawn(move || run(&thread_shared, backoff, sink))
            .ok();
        if thread.is_none() {
            shared.status().last_error = Some("no thread for the link".into());
        }
        Self { shared, thread }
    }

    /// Writes `bytes` to the device (all of them, or an error).
    pub fn send(&self, bytes: &[u8]) -> Result<(), LinkError> {
        let address = || self.shared.address.to_string();
        let mut writer = self.shared.writer();
        let w = writer
            .as_mut()
            .ok_or_else(|| LinkError::NotConnected(address()))?;
        match w.write_all(bytes).and_then(|()| w.flush()) {
            Ok(()) => {
                drop(writer);
                self.shared.status().bytes_out += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                // The reader notices too and reconnects; no more writes till then.
                *writer = None;
                Err(LinkError::Io(address(), e))
            }
        }
    }

    /// The link's state and counters now.
    pub fn status(&self) -> LinkStatus {
        self.shared.status().clone()
    }

    /// The device's address.
    pub fn address(&self) -> &LinkAddress {
        &self.shared.address
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A connection's reading half.
type Reader = Box<dyn Read + Send>;

/// A serial port as a plain reader and writer.
struct Port(Box<dyn serialport::SerialPort>);

impl Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for Port {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

/// Opens the device: its reading half and its writing half.
fn connect(address: &LinkAddress) -> std::io::Result<(Reader, Writer)> {
    match address {
        LinkAddress::Serial { path, baud } => {
            let path = path.to_string_lossy();
            let port = serialport::new(path, *baud)
                .data_bits(serialport::DataBits::Eight)
                .parity(serialport::Parity::None)
                .stop_bits(serialport::StopBits::One)
                .flow_control(serialport::FlowControl::None)
                .timeout(READ_POLL)
                .open()
                .map_err(std::io::Error::from)?;
            let mut writer = port.try_clone().map_err(std::io::Error::from)?;
            writer
                .set_timeout(WRITE_TIMEOUT)
                .map_err(std::io::Error::from)?;
            Ok((Box::new(Port(port)), Box::new(Port(writer))))
        }
        LinkAddress::Tcp { host, port } => {
            let mut last = std::io::Error::new(ErrorKind::NotFound, "no address for the host");
            for addr in (host.as_str(), *port).to_socket_addrs()? {
                match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                    Ok(stream) => {
                        stream.set_nodelay(true)?;
                        stream.set_read_timeout(Some(READ_POLL))?;
                        stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
                        let writer = stream.try_clone()?;
                        return Ok((Box::new(stream), Box::new(writer)));
                    }
                    Err(e) => last = e,
                }
            }
            Err(last)
        }
    }
}

/// The link's thread: connect, read until lost, wait, again, until stopped.
fn run(shared: &Shared, backoff: Backoff, mut sink: impl FnMut(LinkEvent)) {
    let mut wait = backoff.first;
    let mut failures_in_a_row = 0u32;
    while !shared.stop.load(Ordering::Relaxed) {
        shared.status().state = LinkState::Connecting;
        match connect(&shared.address) {
            Ok((reader, writer)) => {
                *shared.writer() = Some(writer);
                {
                    let mut s = shared.status();
                    s.state = LinkState::Up;
                    s.connects += 1;
                }
                tracing::info!("device {}: connected", shared.address);
                failures_in_a_row = 0;
                wait = backoff.first;
                sink(LinkEvent::Connected);
                let reason = read_until_lost(shared, reader, &mut sink);
                *shared.writer() = None;
                if shared.stop.load(Ordering::Relaxed) {
                    break;
                }
                tracing::warn!("device {}: lost ({reason}); reconnecting", shared.address);
                {
                    let mut s = shared.status();
                    s.state = LinkState::Down;
                    s.last_error = Some(reason.clone());
                }
                sink(LinkEvent::Disconnected(reason));
            }
            Err(e) => {
                failures_in_a_row += 1;
                // The first failure, then one line per minute or so.
                if failures_in_a_row == 1 || failures_in_a_row.is_multiple_of(12) {
                    tracing::warn!(
                        "device {}: cannot open ({e}); retrying every {:?} at most",
                        shared.address,
                        backoff.max
                    );
                }
                let mut s = shared.status();
                s.state = LinkState::Down;
                s.last_error = Some(e.to_string());
            }
        }
        sleep_unless_stopped(shared, wait);
        wait = (wait * 2).min(backoff.max);
    }
}

/// Reads and hands on bytes until the connection is lost or the link
/// stops; returns why it ended.
fn read_until_lost(
    shared: &Shared,
    mut reader: Reader,
    sink: &mut impl FnMut(LinkEvent),
) -> String {
    let mut buf = vec![0u8; READ_CHUNK];
    while !shared.stop.load(Ordering::Relaxed) {
        match reader.read(&mut buf) {
            Ok(0) => return "closed by the device".into(),
            Ok(n) => {
                shared.status().bytes_in += n as u64;
                sink(LinkEvent::Bytes(buf[..n].to_vec()));
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                // A writer that failed dropped its half: reconnect.
                if shared.writer().is_none() {
                    return "write failed".into();
                }
            }
            Err(e) => return e.to_string(),
        }
    }
    "stopped".into()
}

fn sleep_unless_stopped(shared: &Shared, wait: Duration) {
    let until = Instant::now() + wait;
    while !shared.stop.load(Ordering::Relaxed) {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return;
        }
        std::thread::sleep(left.min(READ_POLL));
    }
}

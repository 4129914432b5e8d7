//! `ickon emulate transmitter-board|receiver-board`: an [`EmulatedBoard`]
//! on a pseudo-terminal (its path printed, for `serial:PATH`) or a TCP
//! port (`tcp:HOST:PORT`), so that a cell controller, an MSU agent or
//! `ickon device check` can be tried without hardware. The board's clock
//! runs on the system clock with the offset, drift and jitter asked for,
//! and it misbehaves on request (garbage, dropped frames, going silent).
//! A transmitter board logs each burst it fires with the system time it
//! left at.

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use clap::{Args, Subcommand};
use ickon_runtime::link::pty::Pty;
use ickon_runtime::{CommandError, system_now};

use crate::board::{BoardFaults, BoardSpec, Emission, EmulatedBoard};
use crate::emulate_listen::listen_announced;

/// How long a read waits: the resolution of the emulation's loop (a burst
/// is fired at its own time whatever the loop's; only its report waits).
const LOOP_NS: i64 = 1_000_000;

/// Which board to emulate.
#[derive(Debug, Subcommand)]
pub enum EmulateCommand {
    /// A cell's transmitter board: fires armed bursts, reports them.
    TransmitterBoard(TransmitterBoardArgs),
    /// A robot's receiver ring: identifies itself and answers the host
    /// (arrivals come from a simulated world only under `ickon sim`).
    ReceiverBoard(ReceiverBoardArgs),
    /// A Marvelmind hedgehog on a robot of a site: raw distances (0x0004)
    /// and positions (0x0011) at the kit's rate, with its range noise.
    Marvelmind(crate::emulate_hedgehog::MarvelmindArgs),
}

/// Where an emulated board listens, its clock and its faults.
#[derive(Debug, Clone, Args)]
pub struct BoardArgs {
    /// Listen on this TCP address (`HOST:PORT`; port 0 picks one) instead
    /// of a pseudo-terminal.
    #[arg(long, value_name = "HOST:PORT")]
    pub listen: Option<String>,
    /// The board's clock at start, milliseconds.
    #[arg(long, default_value_t = 1000.0)]
    pub clock_offset_ms: f64,
    /// How fast the board's clock runs, ppm.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub drift_ppm: f64,
    /// Standard deviation of the board's timing, microseconds.
    #[arg(long, default_value_t = 0.0)]
    pub jitter_us: f64,
    /// Chance that a frame is preceded by random bytes.
    #[arg(long, default_value_t = 0.0)]
    pub garbage: f64,
    /// Chance that a frame is not sent.
    #[arg(long, default_value_t = 0.0)]
    pub drop: f64,
    /// Stop answering this many seconds after start.
    #[arg(long)]
    pub mute_after_s: Option<f64>,
    /// Seed of the board's random draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// `ickon emulate transmitter-board`.
#[derive(Debug, Clone, Args)]
pub struct TransmitterBoardArgs {
    /// The transmitters it drives, comma-separated ids.
    #[arg(long, value_delimiter = ',', required = true)]
    pub tx: Vec<u32>,
    /// Where it listens, its clock, its faults.
    #[command(flatten)]
    pub board: BoardArgs,
}

/// `ickon emulate receiver-board`.
#[derive(Debug, Clone, Args)]
pub struct ReceiverBoardArgs {
    /// Receivers on the ring, evenly spaced.
    #[arg(long, default_value_t = 6)]
    pub receivers: u8,
    /// Where it listens, its clock, its faults.
    #[command(flatten)]
    pub board: BoardArgs,
}

/// Runs `ickon emulate` until Ctrl-C.
pub fn run_emulate(command: EmulateCommand) -> Result<(), CommandError> {
    let (mut spec, args) = match command {
        EmulateCommand::TransmitterBoard(a) => {
            (BoardSpec::transmitter(&a.tx, a.board.seed), a.board)
        }
        EmulateCommand::ReceiverBoard(a) => {
            (BoardSpec::receiver(a.receivers, a.board.seed), a.board)
        }
        EmulateCommand::Marvelmind(a) => return crate::emulate_hedgehog::run_marvelmind(a),
    };
    spec.clock_offset_ns =
        checked(args.clock_offset_ms * 1e6, "--clock-offset-ms", 0.0, 1e12)? as i64;
    spec.drift_ppm = checked(args.drift_ppm, "--drift-ppm", -1000.0, 1000.0)?;
    spec.jitter_ns = checked(args.jitter_us * 1e3, "--jitter-us", 0.0, 1e6)?;
    spec.faults = BoardFaults {
        garbage: checked(args.garbage, "--garbage", 0.0, 1.0)?,
        drop: checked(args.drop, "--drop", 0.0, 1.0)?,
        mute_after_ns: args
            .mute_after_s
            .map(|s| checked(s * 1e9, "--mute-after-s", 0.0, 1e15).map(|n| n as i64))
            .transpose()?,
    };
    let mut board = EmulatedBoard::new(spec, system_now().as_nanos());
    // Until Ctrl-C or SIGTERM ends the process: the board holds nothing
    // that must be saved.
    match &args.listen {
        Some(addr) => serve_tcp(&mut board, addr),
        None => serve_pty(&mut board),
    }
}

fn checked(v: f64, flag: &str, lo: f64, hi: f64) -> Result<f64, CommandError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(CommandError::bad_input(format!(
            "{flag}: {v} is outside {lo}..={hi}"
        )))
    }
}

fn serve_pty(board: &mut EmulatedBoard) -> Result<(), CommandError> {
    let pty = Pty::open().map_err(|e| CommandError::failure(format!("pseudo-terminal: {e}")))?;
    println!("serial:{}", pty.path().display());
    let _ = std::io::stdout().flush();
    let (reader, writer) = pty
        .device_end(Duration::from_nanos(LOOP_NS as u64))
        .map_err(|e| CommandError::failure(format!("pseudo-terminal: {e}")))?;
    serve(board, reader, writer).map_err(|e| CommandError::failure(format!("pseudo-terminal: {e}")))
}

fn serve_tcp(board: &mut EmulatedBoard, addr: &str) -> Result<(), CommandError> {
    let listener = listen_announced(addr)?;
    // One host at a time; the board (and its clock) outlives connections.
    for stream in listener.incoming() {
        let stream = match stream {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!("emulated board: accept: {e}");
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        let prepared = stream
            .set_read_timeout(Some(Duration::from_nanos(LOOP_NS as u64)))
            .and_then(|()| stream.try_clone());
        match prepared {
            Ok(writer) => {
                tracing::info!("emulated board: host connected");
                if let Err(e) = serve(board, stream, writer) {
                    tracing::info!("emulated board: host gone ({e})");
                }
            }
            Err(e) => tracing::warn!("emulated board: {e}"),
        }
    }
    Ok(())
}

/// Answers one host until the connection ends.
fn serve(
    board: &mut EmulatedBoard,
    mut reader: impl Read,
    mut writer: impl Write,
) -> std::io::Result<()> {
    let mut buf = [0u8; 4096];
    loop {
        let now = system_now().as_nanos();
        let mut out = match reader.read(&mut buf) {
            Ok(0) => return Err(ErrorKind::UnexpectedEof.into()),
            Ok(n) => board.on_bytes(now, &buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                Vec::new()
            }
            Err(e) => return Err(e),
        };
        let (fired, emissions) = board.fire_due(system_now().as_nanos());
        out.extend(fired);
        for Emission {
            tx_id,
            reference_ns,
        } in emissions
        {
            tracing::info!("emulated board: tx {tx_id} fired at {reference_ns} ns (system clock)");
        }
        if !out.is_empty() {
            writer.write_all(&out)?;
            writer.flush()?;
        }
    }
}

//! `ickon emulate marvelmind`: an [`EmulatedHedgehog`] streaming in real
//! time on a pseudo-terminal (its path printed, for
//! `marvelmind:serial:PATH`) or a TCP port (for `marvelmind:tcp:HOST:PORT`),
//! so that an MSU agent can be tried with a Marvelmind kit's stream and no
//! kit. A hedgehog only writes: nothing the host sends is read.

use std::f64::consts::TAU;
use std::io::Write;
use std::net::TcpStream;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use clap::Args;
use ickon_proto::site::Site;
use ickon_runtime::link::pty::Pty;
use ickon_runtime::{CommandError, system_now};

use crate::hedgehog::{EmulatedHedgehog, HedgehogSpec, Update};
use ickon_sim::robot::DriveSpec;

/// Updates waiting for a pseudo-terminal's host (two seconds at the default rate).
const PTY_QUEUE: usize = 16;

/// How long a write to a TCP host may block before the host is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_millis(500);

/// `ickon emulate marvelmind`.
#[derive(Debug, Clone, Args)]
pub struct MarvelmindArgs {
    /// The site: its transmitters are the kit's beacons (ids as
    /// addresses), its robot's route is driven.
    #[arg(long, value_name = "FILE")]
    pub site: PathBuf,
    /// The robot carrying the hedgehog (default: the site's first).
    #[arg(long)]
    pub robot: Option<String>,
    /// Listen on this TCP address (`HOST:PORT`; port 0 picks one) instead
    /// of a pseudo-terminal.
    #[arg(long, value_name = "HOST:PORT")]
    pub listen: Option<String>,
    /// Updates per second (a kit streams at 1-16 Hz, depending on its
    /// beacons and settings).
    #[arg(long, default_value_t = 8.0)]
    pub rate_hz: f64,
    /// One-sigma noise of one distance, metres (Marvelmind's stated ±2 cm).
    #[arg(long, default_value_t = 0.02)]
    pub range_sigma_m: f64,
    /// The speed of sound the kit is set to, m/s (the site's temperature
    /// gives the true one).
    #[arg(long, default_value_t = 343.0)]
    pub speed_of_sound_m_s: f64,
    /// The hedgehog's own address.
    #[arg(long, default_value_t = 9)]
    pub address: u8,
    /// Chance that a frame is preceded by random bytes.
    #[arg(long, default_value_t = 0.0)]
    pub garbage: f64,
    /// Chance that a frame is not sent.
    #[arg(long, default_value_t = 0.0)]
    pub drop: f64,
    /// Seed of the noise and the faults.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// With `--listen`: the robot waits at its start until a host first
    /// connects (a robot that sets off once its localisation is up).
    #[arg(long)]
    pub wait_for_host: bool,
    /// Writes the robot's true pose and its wheel encoders' counts at every
    /// update to this CSV file (`time_ns,x_m,y_m,theta_rad,left_ticks,right_ticks`,
    /// system clock; a Pioneer 3-DX drive without slip), to score what an
    /// MSU made of the stream, or to play the robot's odometry.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
}

/// Runs `ickon emulate marvelmind` until Ctrl-C.
pub fn run_marvelmind(args: MarvelmindArgs) -> Result<(), CommandError> {
    let (site, _, _) = Site::load_or_default(Some(&args.site))
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let robot = match &args.robot {
        Some(r) => r.clone(),
        None => site
            .robots
            .first()
            .map(|r| r.id.clone())
            .ok_or_else(|| CommandError::bad_input("the site has no robot"))?,
    };
    let in_range = |v: f64, flag: &str, lo: f64, hi: f64| {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(CommandError::bad_input(format!(
                "{flag}: {v} is outside {lo}..={hi}"
            )))
        }
    };
    let spec = HedgehogSpec {
        robot,
        rate_hz: in_range(args.rate_hz, "--rate-hz", 0.1, 100.0)?,
        range_sigma_m: in_range(args.range_sigma_m, "--range-sigma-m", 0.0, 10.0)?,
        kit_speed_of_sound_m_s: in_range(
            args.speed_of_sound_m_s,
            "--speed-of-sound-m-s",
            300.0,
            370.0,
        )?,
        garbage: in_range(args.garbage, "--garbage", 0.0, 1.0)?,
        drop: in_range(args.drop, "--drop", 0.0, 1.0)?,
        address: args.address,
        seed: args.seed,
    };
    let mut hedgehog =
        EmulatedHedgehog::new(&site, spec).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let mut truth = match &args.truth {
        Some(path) => {
            let mut f = std::fs::File::create(path)
                .map_err(|e| CommandError::failure(format!("--truth {}: {e}", path.display())))?;
            writeln!(f, "time_ns,x_m,y_m,theta_rad,left_ticks,right_ticks")
                .map_err(|e| CommandError::failure(e.to_string()))?;
            Some(f)
        }
        None => None,
    };
    let mut line = match &args.listen {
        Some(addr) => Line::tcp(addr)?,
        None => Line::pty()?,
    };
    let period = Duration::from_secs_f64(hedgehog.period_s());
    let ticks_per_turn = DriveSpec::default().ticks_per_turn;
    let mut due = Instant::now();
    // Until Ctrl-C or SIGTERM ends the process: nothing to save.
    loop {
        due += period;
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        if args.wait_for_host && !line.has_host() {
            continue;
        }
        let Update {
            truth: pose, bytes, ..
        } = hedgehog.update();
        if let Some(f) = truth.as_mut() {
            let now = system_now().as_nanos();
            let ticks = |wheel_rad: f64| (wheel_rad / TAU * ticks_per_turn).round() as i64;
            writeln!(
                f,
                "{now},{:.4},{:.4},{:.5},{},{}",
                pose.x_m,
                pose.y_m,
                pose.theta_rad,
                ticks(pose.left_wheel_rad),
                ticks(pose.right_wheel_rad)
            )
            .and_then(|()| f.flush())
            .map_err(|e| CommandError::failure(format!("--truth: {e}")))?;
        }
        line.write(&bytes);
    }
}

/// Where the stream goes.
enum Line {
    /// A pseudo-terminal, written by a thread of its own: updates the host
    /// does not read in time are dropped (as a USB port's buffer
    /// overflows), and the robot keeps its pace.
    Pty {
        /// Held: the path lives as long as the pair.
        _pair: Pty,
        queue: SyncSender<Vec<u8>>,
    },
    /// The TCP host connected last, if any.
    Tcp(Arc<Mutex<Option<TcpStream>>>, Arc<AtomicBool>),
}

impl Line {
    fn pty() -> Result<Self, CommandError> {
        let failed = |e: std::io::Error| CommandError::failure(format!("pseudo-terminal: {e}"));
        let pty = Pty::open().map_err(failed)?;
        println!("serial:{}", pty.path().display());
        let _ = std::io::stdout().flush();
        let (_, mut writer) = pty.device_end(Duration::ZERO).map_err(failed)?;
        let (tx, rx) = sync_channel::<Vec<u8>>(PTY_QUEUE);
        std::thread::spawn(move || {
            for bytes in rx {
                let _ = writer.write_all(&bytes);
            }
        });
        Ok(Line::Pty {
            _pair: pty,
            queue: tx,
        })
    }

    fn tcp(addr: &str) -> Result<Self, CommandError> {
        let listener = crate::emulate_listen::listen_announced(addr)?;
        let host = Arc::new(Mutex::new(None));
        let ever = Arc::new(AtomicBool::new(false));
        let (accepted, connected) = (host.clone(), ever.clone());
        // A new host replaces the old one: a hedgehog has one port.
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                match stream {
                    Ok(s) => {
                        let _ = s.set_nodelay(true);
                        let _ = s.set_write_timeout(Some(WRITE_TIMEOUT));
                        tracing::info!("emulated hedgehog: host connected");
                        *accepted.lock().unwrap_or_else(PoisonError::into_inner) = Some(s);
                        connected.store(true, Ordering::Relaxed);
                    }
                    Err(e) => tracing::warn!("emulated hedgehog: accept: {e}"),
                }
            }
        });
        Ok(Line::Tcp(host, ever))
    }

    /// Whether a host ever connected (a pseudo-terminal cannot tell: yes).
    fn has_host(&self) -> bool {
        match self {
            Line::Pty { .. } => true,
            Line::Tcp(_, ever) => ever.load(Ordering::Relaxed),
        }
    }

    fn write(&mut self, bytes: &[u8]) {
        match self {
            Line::Pty { queue, .. } => {
                let _ = queue.try_send(bytes.to_vec());
            }
            Line::Tcp(host, _) => {
                let mut host = host.lock().unwrap_or_else(PoisonError::into_inner);
                if let Some(s) = host.as_mut()
                    && let Err(e) = s.write_all(bytes)
                {
                    tracing::info!("emulated hedgehog: host gone ({e})");
                    *host = None;
                }
            }
        }
    }
}

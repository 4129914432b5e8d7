//! `ickon record`: every message of a running site into an MCAP file that
//! Foxglove and `ros2 bag` open (ROS 2 profile; [`writer`] says how the file
//! is laid out and why a killed recorder leaves it readable).
//!
//! The recorder joins the site like any node (the same Zenoh flags; with
//! none, the run file of an `ickon sim` on this machine), subscribes to
//! `ickon/<site>/**` (or `--keys`), asks the central unit for the site and
//! the schedule once, and stores each message with its receive time as the
//! MCAP log time and its own event time as the publish time ([`channels`]).
//! `ickon sim --record FILE` runs the same loop ([`live`]) in the launcher.

pub mod bench;
pub mod channels;
pub mod live;
pub mod sim_hook;
#[cfg(test)]
mod tests;
pub mod view;
pub mod writer;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use ickon_proto::keys::Keys;
use ickon_runtime::{RunDir, ZenohArgs};

use ickon_runtime::CommandError;
pub use writer::{RecordError, RecordStats, Recorder};

/// Arguments of `ickon record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// The MCAP file to write (refused if it exists).
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many seconds (default: at Ctrl-C or SIGTERM).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Record only the keys matching this Zenoh key expression (default:
    /// `ickon/<site>/**`, everything of the site).
    #[arg(long)]
    pub keys: Option<String>,
    /// Zenoh connection flags; with neither `-c` nor `-e`, the run file of an
    /// `ickon sim` of the site on this machine says where to connect.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Site name, the `<site>` of every key.
    #[arg(long, default_value = "lab")]
    pub site_name: String,
    /// Throughput measurement instead of a site: write the message mix of
    /// this many simulated robots (the rates of `ickon sim`) for
    /// `--duration` seconds of site time (60 by default) as fast as possible.
    #[arg(long)]
    pub synthetic_robots: Option<usize>,
    /// Print one JSON document on stdout instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Hold the Foxglove view too: the channels the central unit's
    /// Foxglove server shows live (site scene, cells, robots, `/tf`, plots,
    /// log), beside the site's streams, so that the recording looks in
    /// Foxglove as the live view does. Their encodings are Foxglove's
    /// (protobuf, JSON), and rosbag2 opens only files whose topics share
    /// one serialization format: such a file is for Foxglove and `ickon
    /// replay mcap`, not for `ros2 bag`.
    #[arg(long)]
    pub foxglove_view: bool,
}

/// What a recording reports at its end.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RecordReport {
    /// The file written.
    pub file: String,
    /// Its size in bytes.
    pub file_bytes: u64,
    /// Seconds of site time covered (first to last receive time).
    pub duration_s: f64,
    /// Messages per second of site time.
    pub messages_per_s: f64,
    /// File megabytes (10^6 bytes) per minute of site time.
    pub mb_per_min: f64,
    /// CPU seconds (user + system) of the whole process while recording.
    pub cpu_s: f64,
    /// Wall-clock seconds spent recording.
    pub wall_s: f64,
    /// The counters.
    #[serde(flatten)]
    pub stats: RecordStats,
}

impl RecordReport {
    fn new(file: &Path, stats: RecordStats, cpu_s: f64, wall_s: f64) -> Self {
        let file_bytes = std::fs::metadata(file).map_or(0, |m| m.len());
        let duration_s = match (stats.first_ns, stats.last_ns) {
            (Some(a), Some(b)) if b > a => (b - a) as f64 * 1e-9,
            _ => 0.0,
        };
        let per_s = |v: f64| {
            if duration_s > 0.0 {
                v / duration_s
            } else {
                0.0
            }
        };
        Self {
            file: file.display().to_string(),
            file_bytes,
            duration_s,
            messages_per_s: per_s(stats.messages as f64),
            mb_per_min: per_s(file_bytes as f64) * 60.0 / 1e6,
            cpu_s,
            wall_s,
            stats,
        }
    }

    /// The summary printed at the end.
    pub fn render(&self) -> String {
        let mut s = format!(
            "recorded {} messages on {} topics, {:.1} s of site time, into {} ({:.2} MB): {:.0} messages/s, {:.2} MB/min, CPU {:.2} s in {:.1} s ({:.1} % of one core)\n",
            self.stats.messages,
            self.stats.per_topic.len(),
            self.duration_s,
            self.file,
            self.file_bytes as f64 / 1e6,
            self.messages_per_s,
            self.mb_per_min,
            self.cpu_s,
            self.wall_s,
            if self.wall_s > 0.0 {
                100.0 * self.cpu_s / self.wall_s
            } else {
                0.0
            },
        );
        if self.stats.undecodable > 0 {
            s.push_str(&format!(
                "  {} messages did not decode as their key's type and were not recorded\n",
                self.stats.undecodable
            ));
        }
        s
    }
}

/// CPU seconds (user + system) this process has used so far.
pub fn cpu_seconds() -> f64 {
    use nix::sys::resource::{UsageWho, getrusage};
    getrusage(UsageWho::RUSAGE_SELF).map_or(0.0, |u| {
        let secs = |t: nix::sys::time::TimeVal| t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6;
        secs(u.user_time()) + secs(u.system_time())
    })
}

/// Creates the output file (never over an existing one), buffered.
pub fn create_output(path: &Path) -> Result<BufWriter<File>, String> {
    File::create_new(path)
        .map(|f| BufWriter::with_capacity(1 << 20, f))
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => format!(
                "{} exists: a recording is never overwritten; remove it or choose another name",
                path.display()
            ),
            _ => format!("cannot create {}: {e}", path.display()),
        })
}

/// The message a recording stopped by a write error ends with.
pub fn write_failure(path: &Path, e: &RecordError) -> String {
    if e.disk_full() {
        format!(
            "the disk is full: the recording {} stopped ({e}); what was written up to the last chunk (at most {} s before) is readable",
            path.display(),
            writer::FLUSH_EVERY.as_secs()
        )
    } else {
        format!(
            "the recording {} stopped: {e}; what was written up to the last chunk is readable",
            path.display()
        )
    }
}

/// The metadata record every recording starts with.
pub fn base_metadata(site: &str) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut m = BTreeMap::new();
    m.insert(
        "ickon".to_string(),
        BTreeMap::from([
            ("site".to_string(), site.to_string()),
            (
                "recorder".to_string(),
                env!("CARGO_PKG_VERSION").to_string(),
            ),
        ]),
    );
    m
}

/// Runs `ickon record` and returns the exit code.
pub fn run(args: RecordArgs) -> Result<(), CommandError> {
    if let Some(d) = args.duration
        && !(d.is_finite() && d > 0.0 && d <= 7.0 * 86_400.0)
    {
        return Err(CommandError::bad_input(
            "--duration must be between 0 and 604800 seconds",
        ));
    }
    let keys = Keys::new(&args.site_name)
        .map_err(|e| CommandError::bad_input(format!("--site-name: {e}")))?;
    let pattern = args.keys.clone().unwrap_or_else(|| keys.everything());
    if let Err(e) = zenoh::key_expr::KeyExpr::try_from(pattern.as_str()) {
        return Err(CommandError::bad_input(format!(
            "--keys {pattern:?} is not a key expression: {e}"
        )));
    }
    if let Some(n) = args.synthetic_robots {
        return bench::run(&args, &keys, n);
    }
    let zenoh_flags = connection(&args).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let out = create_output(&args.out).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let mut recorder = match Recorder::new(out, keys.clone(), &base_metadata(&args.site_name)) {
        Ok(r) => r,
        Err(e) => {
            return Err(CommandError::failure(
                write_failure(&args.out, &e).to_string(),
            ));
        }
    };
    let started = Instant::now();
    let cpu0 = cpu_seconds();
    let outcome = ickon_runtime::block_on(2, async {
        let session = zenoh_flags
            .open()
            .await
            .map_err(|e| format!("cannot join the site: {e}"))?;
        let duration = args.duration;
        let stop = async move {
            let shutdown = ickon_runtime::shutdown_signal(false);
            match duration {
                Some(d) => {
                    tokio::select! {
                        _ = shutdown => {}
                        _ = tokio::time::sleep(std::time::Duration::from_secs_f64(d)) => {}
                    }
                }
                None => shutdown.await,
            }
        };
        if !args.json {
            eprintln!(
                "ickon record: recording {pattern} into {} (Ctrl-C stops)",
                args.out.display()
            );
        }
        let with_view = args.foxglove_view;
        let r = live::record_site(&session, &keys, &pattern, &mut recorder, with_view, stop).await;
        let _ = session.close().await;
        r.map_err(|e| match e {
            live::LiveError::Record(e) => write_failure(&args.out, &e),
            other => other.to_string(),
        })
    });
    let failure = match outcome {
        Some(Ok(())) => None,
        Some(Err(e)) => Some(e),
        None => Some("the recorder's runtime failed".to_string()),
    };
    if let Some(why) = failure {
        return Err(CommandError::failure(why.to_string()));
    }
    let stats = match recorder.finish() {
        Ok((stats, out)) => match out.into_inner().map(|f| f.sync_all()) {
            Ok(Ok(())) => stats,
            Ok(Err(e)) => {
                return Err(CommandError::failure(
                    write_failure(&args.out, &RecordError::Write(e)).to_string(),
                ));
            }
            Err(e) => {
                let e = RecordError::Write(e.into_error());
                return Err(CommandError::failure(
                    write_failure(&args.out, &e).to_string(),
                ));
            }
        },
        Err(e) => {
            return Err(CommandError::failure(
                write_failure(&args.out, &e).to_string(),
            ));
        }
    };
    let report = RecordReport::new(
        &args.out,
        stats,
        cpu_seconds() - cpu0,
        started.elapsed().as_secs_f64(),
    );
    if args.json {
        match serde_json::to_string_pretty(&report) {
            Ok(s) => println!("{s}"),
            Err(e) => eprintln!("error: {e}"),
        }
    } else {
        eprint!("{}", report.render());
    }
    Ok(())
}

/// Where to connect: the flags, or the run file of an `ickon sim` of the
/// site. The recorder is a peer (like the nodes), so that it hears every
/// node directly.
fn connection(args: &RecordArgs) -> Result<ZenohArgs, String> {
    if args.zenoh.names_a_peer() {
        return Ok(args.zenoh.clone());
    }
    let run = RunDir::standard().read(&args.site_name).map_err(|e| {
        format!(
            "{e}\n  give -e/--connect ENDPOINT or --zenoh-config FILE to record a site elsewhere"
        )
    })?;
    Ok(ZenohArgs {
        connect: run.central,
        listen: if args.zenoh.listen.is_empty() {
            vec!["tcp/127.0.0.1:0".into()]
        } else {
            args.zenoh.listen.clone()
        },
        no_multicast_scouting: true,
        ..ZenohArgs::default()
    })
}

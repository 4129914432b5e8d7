//! `rosbags` (PyPI), the independent ROS 2 CDR implementation the ROS 2
//! tests check against, run through `tests/ros2/rosbags_cdr.py`.
//!
//! The Python with `rosbags` installed is named by `ICKON_ROS_PYTHON`
//! (`.ci/run` makes a virtual environment and sets it). Unset, a test is
//! skipped with a message, so that a clean clone's tests pass anywhere;
//! set to a Python that is missing, it fails: the check must not silently
//! vanish where it was asked for.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

/// The environment variable naming the Python that has `rosbags`.
pub const PYTHON_ENV: &str = "ICKON_ROS_PYTHON";

/// A Python with `rosbags` and the helper script.
pub struct Rosbags {
    python: PathBuf,
    script: PathBuf,
}

impl Rosbags {
    /// The configured Python, or `None` (the caller skips, said in one
    /// line) when [`PYTHON_ENV`] is unset.
    ///
    /// # Panics
    /// When [`PYTHON_ENV`] names nothing: a Python asked for explicitly
    /// (as `.ci/run` does) must be there.
    pub fn find() -> Option<Self> {
        let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("ros2/rosbags_cdr.py");
        match std::env::var_os(PYTHON_ENV)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
        {
            Some(python) if python.exists() => Some(Self { python, script }),
            Some(python) => panic!(
                "{PYTHON_ENV} names {}, which is missing (.ci/run makes it)",
                python.display()
            ),
            None => {
                eprintln!(
                    "skipped: {PYTHON_ENV} is unset: set it to a Python with rosbags (see .ci/run)"
                );
                None
            }
        }
    }

    /// Runs the script with `args`, `stdin` on its input; its output.
    ///
    /// # Panics
    /// When the script fails.
    pub fn run(&self, args: &[&str], stdin: &str) -> String {
        let mut child = Command::new(&self.python)
            .arg(&self.script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start the rosbags helper");
        child
            .stdin
            .take()
            .expect("stdin")
            .write_all(stdin.as_bytes())
            .expect("write to the rosbags helper");
        let out = child.wait_with_output().expect("rosbags helper output");
        assert!(
            out.status.success(),
            "rosbags helper {args:?} failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("UTF-8 output")
    }
}

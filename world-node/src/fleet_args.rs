//! The flags of a node that simulates robots: the world (`ickon node
//! world`) and the synthetic fleet (`ickon node synthetic-fleet`) are
//! given the same mesh, robots, noise profile and seed.

use clap::Args;
use ickon_runtime::NodeArgs;

/// The mesh, the robots, their noise and the seed of a node that simulates
/// robots (flattened into `WorldArgs` and `SyntheticFleetArgs`).
#[derive(Debug, Clone, Args)]
pub struct SimulatedRobotsArgs {
    /// Connection flags.
    #[command(flatten)]
    pub mesh: NodeArgs,
    /// Robots to simulate, comma-separated ids of the site.
    #[arg(long, value_delimiter = ',', required = true)]
    pub robots: Vec<String>,
    /// Noise profile: ideal, paper, building, harsh, or a TOML file
    /// (deploy/profiles/paper.toml is a template). The world simulates all
    /// of it; the synthetic fleet's fixes follow its timing noise and range.
    #[arg(long, default_value = "paper")]
    pub profile: String,
    /// Seed of every random draw (the world's; the synthetic fleet's fixes'
    /// noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

//! What sits between the cell's timer and its transmitters. The driver is
//! chosen when the cell starts (`--driver`): the simulation's, or a
//! transmitter board over a serial line or TCP (`crate::device`).

use ickon_proto::msg::control::Burst;

use crate::timer::PlannedBurst;

/// Why a transmitter could not be programmed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DriverError {
    /// The transmitter id is not wired to this cell.
    #[error("transmitter {0} is not driven by this cell")]
    UnknownTransmitter(u32),
    /// The hardware refused or did not answer.
    #[error("transmitter hardware: {0}")]
    Hardware(String),
}

/// A cell's transmitters.
pub trait TransmitterDriver: Send {
    /// Programs transmitter `burst.tx_id` to fire at local time `burst.local`
    /// (a little ahead: the hardware keeps the time; `master` is when it was
    /// scheduled on the master time base). Returns the emission report to
    /// publish on `cell/<id>/burst` when it is known at once, or `None` when
    /// the hardware reports the firing later (a board's `Fired`).
    fn program(&mut self, burst: &PlannedBurst) -> Result<Option<Burst>, DriverError>;
}

/// The simulation's transmitters: a burst is emitted exactly when the cell's
/// clock reads its programmed local time, and the report carries that true
/// time (`true_time` maps the cell's local clock to true time), so the
/// operating system's timer jitter does not enter the measurement and the
/// synchronisation error does.
pub struct SimulatedDriver<F> {
    cell_id: String,
    true_time: F,
}

impl<F> SimulatedDriver<F> {
    /// A driver for `cell_id` whose clock maps to true time by `true_time`.
    pub fn new(cell_id: &str, true_time: F) -> Self {
        Self {
            cell_id: cell_id.to_string(),
            true_time,
        }
    }
}

impl<F> TransmitterDriver for SimulatedDriver<F>
where
    F: Fn(ickon_proto::time::Time) -> ickon_proto::time::Time + Send,
{
    fn program(&mut self, b: &PlannedBurst) -> Result<Option<Burst>, DriverError> {
        Ok(Some(Burst {
            cell_id: self.cell_id.clone(),
            tx_id: b.tx_id,
            cycle: b.cycle,
            scheduled: b.master,
            actual: (self.true_time)(b.local),
            epoch: b.epoch,
        }))
    }
}

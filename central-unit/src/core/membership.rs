//! Which cells are in the schedule: liveliness, status, bursts, and the
//! new schedule version when the live set changes.

use ickon_proto::msg::admin::CellState;
use ickon_proto::msg::control::{Burst, CellStatus, Schedule};
use ickon_proto::time::Time;

use super::{CentralCore, Output, make_schedule};

impl CentralCore {
    /// The first cycle whose trigger leaves at least `schedule_announce` after `now`.
    pub(super) fn first_announceable_cycle(&self, now: Time) -> u64 {
        let period = self.schedule_for(self.next_cycle).cycle_period;
        let mut cycle = self.next_cycle;
        let mut trigger_at = self.next_trigger_at();
        // A positive period is guaranteed by the scheduler; the bound keeps a
        // degenerate one from looping.
        for _ in 0..1_000 {
            if trigger_at.since(now) >= self.config.schedule_announce {
                break;
            }
            cycle += 1;
            trigger_at = trigger_at + period;
        }
        cycle
    }

    /// A new schedule when the live cells differ from the scheduled ones.
    pub(super) fn reconcile_membership(&mut self, now: Time) -> Option<Output> {
        if !self.any_cell_seen {
            return None;
        }
        let live: Vec<String> = self
            .site
            .cells
            .iter()
            .filter(|c| self.cells.get(&c.id).is_some_and(|s| s.alive))
            .map(|c| c.id.clone())
            .collect();
        if live.is_empty() || live == self.latest_schedule().active_cells {
            return None;
        }
        // A forged schedule may have pushed the version to the last one.
        let Some(version) = self.latest_schedule().version.checked_add(1) else {
            tracing::warn!("no schedule version left in epoch {}", self.epoch);
            return None;
        };
        let effective = self.first_announceable_cycle(now);
        let schedule = Schedule {
            epoch: self.epoch,
            ..make_schedule(self.config.schedule, &self.site, &live, version, effective).ok()?
        };
        tracing::info!(
            "schedule v{version} from cycle {effective}: cells {}",
            live.join(", ")
        );
        self.push_schedule(schedule.clone());
        Some(Output::Schedule(schedule))
    }

    /// Adds a schedule and forgets those no cycle from the last triggered on uses.
    pub(super) fn push_schedule(&mut self, schedule: Schedule) {
        self.schedules.push(schedule);
        let oldest_used = self.schedule_for(self.last_cycle()).version;
        self.schedules.retain(|s| s.version >= oldest_used);
    }

    /// Recomputes the state of every cell at `now` and notes the cycle of
    /// every change.
    pub(super) fn update_states(&mut self, now: Time) {
        let cycle = self.last_cycle();
        let scheduled = self.schedule_for(cycle).active_cells.clone();
        for (id, c) in &mut self.cells {
            let in_schedule = scheduled.contains(id);
            let state = c.state_at(now, in_schedule);
            if state != c.state {
                // Up and idle alternate with the robots' positions: only
                // going down and coming back are news.
                if let Some(why) = c.down_reason(now, in_schedule).filter(|_| c.alive) {
                    tracing::warn!("cell {id} is down from cycle {cycle}: {why}");
                } else if c.state == CellState::Down && state != CellState::Down {
                    tracing::info!("cell {id} is {} from cycle {cycle}", state.name());
                }
                c.state = state;
                c.state_since_cycle = cycle;
            }
        }
    }

    /// A cell's liveliness token appeared (`up`) or disappeared at `now`;
    /// the schedule that follows from it, if any.
    pub(super) fn cell_alive(&mut self, id: &str, up: bool, now: Time) -> Vec<Output> {
        let Some(c) = self.cells.get_mut(id) else {
            tracing::warn!("liveliness of unknown cell {id:?} ignored");
            return Vec::new();
        };
        c.alive = up;
        self.any_cell_seen |= up;
        tracing::info!("cell {id} is {}", if up { "up" } else { "down" });
        let out: Vec<Output> = self.reconcile_membership(now).into_iter().collect();
        self.update_states(now);
        out
    }

    /// A cell's status report, received at `now`.
    pub(super) fn on_cell_status(&mut self, status: CellStatus, now: Time) {
        if let Some(c) = self.cells.get_mut(&status.cell_id) {
            c.on_status(status, now);
        }
    }

    /// A burst report, its `actual` emission time on the master time base.
    /// Bursts of another epoch answer another central unit's triggers.
    pub(super) fn on_burst(&mut self, burst: &Burst, now: Time) {
        if burst.epoch != self.epoch {
            return;
        }
        if let Some(c) = self.cells.get_mut(&burst.cell_id) {
            c.on_burst(burst, now);
        }
    }
}

//! End-to-end tests that replay recorded data through `ickon replay`:
//! the UTIL flights and the CMU Plaza runs under `ICKON_DATA` (skipped
//! without it unless `ICKON_REQUIRE_DATA=1`), and the arrival-time logs
//! of the repository. One module per subject.

mod replay_cli;
mod replay_plaza;
mod replay_tdoa;
mod util_flights;

//! Integration tests of ICKON-rs live in `tests/`; this library holds shared helpers.

//! Random input sequences.

//! The site model (placeholder while it is written).

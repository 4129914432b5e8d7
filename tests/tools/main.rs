//! End-to-end tests that need a tool from outside the build: headless
//! Chromium, Python with PyPI packages (`mcap`, `rosbags`), root for
//! network namespaces (the deployment guide's test). Each names
//! what it needs in `docs/testing.md` and skips without it unless asked
//! for it. One module per subject.

mod deploy_docs;
mod figures_script;
mod foxglove_app;
mod netns_lan;
mod record_mcap;
mod ros2_msu;
mod ros2_topics;
mod web_map;

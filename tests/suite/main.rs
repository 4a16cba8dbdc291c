//! The integration test suite: one binary, one module per topic (a binary per file would link
//! the crate 29 times). Shared fixtures live in `common`, `sim_support` and `sync_support`.

mod common;
mod sim_support;
mod sync_support;

mod calib_boresight;
mod calib_e2e;
mod calib_latency;
mod calib_sphere;
mod calib_tripod_scans;
mod cli;
mod config_files;
mod diagnose;
mod diagnose_acceptance;
mod epsg_frames;
mod frames;
mod fuzz;
mod geodesy;
mod geodesy_local;
mod geoid;
mod io_atomic;
mod io_bad_input;
mod io_info;
mod io_profiles_csv;
mod las_pinned;
mod las_roundtrip;
mod laz_output;
mod pipeline_roundtrip;
mod pipelines;
mod realdata;
mod realdata_leeward;
mod safety_collisions;
mod safety_messages;
mod safety_publish;
mod sim_effects;
mod sim_references;
mod sim_stats;
mod sim_tie;
mod sync_paper_stats;
mod sync_pipeline;
mod sync_robust;
mod uncertainty_latency_table;
mod uncertainty_model;
mod uncertainty_parking_lot;
mod uncertainty_pipeline;
mod uncertainty_sobol;

//! File formats that cross the project's boundary (conventions §6 and 7).

pub mod atomic;
pub mod config_file;
pub mod copc;
pub mod counters;
pub mod csd;
pub(crate) mod csv_text;
pub(crate) mod digest;
pub(crate) mod direct;
pub mod gnss;
pub mod imu;
pub mod info;
pub mod las;
pub mod laz;
pub(crate) mod mapped;
pub mod patches;
pub mod paths;
pub mod points;
pub mod profiles;
pub mod profiles_csv;
pub(crate) mod publish;
pub mod sbet;
pub mod smrmsg;
pub(crate) mod spill;
pub mod timed;

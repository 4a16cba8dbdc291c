//! File formats that cross the project's boundary (SPEC 6 and 7).

pub mod atomic;
pub mod las;
pub mod mapped;
pub mod profiles;
pub mod sbet;
pub mod smrmsg;

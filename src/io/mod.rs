//! File formats that cross the project's boundary (SPEC 6 and 7).
pub mod las;

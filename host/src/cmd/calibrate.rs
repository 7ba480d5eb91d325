//! `cta calibrate`.

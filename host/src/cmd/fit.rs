//! `cta fit`.

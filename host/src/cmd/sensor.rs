//! `cta sensor`.

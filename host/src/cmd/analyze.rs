//! `cta analyze`.

//! `cta evaluate`.

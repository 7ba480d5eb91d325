//! `cta uncertainty`.

//! `cta beacon`.

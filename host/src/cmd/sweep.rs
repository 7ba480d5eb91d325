//! `cta sweep`.

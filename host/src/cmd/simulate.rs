//! `cta simulate`.

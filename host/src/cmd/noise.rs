//! `cta noise`.

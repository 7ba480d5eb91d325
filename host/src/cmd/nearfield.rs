//! `cta nearfield`.

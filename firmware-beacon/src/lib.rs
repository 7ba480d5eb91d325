//! Firmware logic (host-testable). Filled by its issue.
#![no_std]

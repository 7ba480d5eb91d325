//! One module a command: its clap arguments, the library call, and the rendering of the
//! result as text or JSON.

pub mod analyze;
pub mod beacon;
pub mod calibrate;
pub mod completions;
pub mod demo;
pub mod evaluate;
pub mod fit;
pub mod nearfield;
pub mod noise;
pub mod pose;
pub mod sensor;
pub mod simulate;
pub mod sweep;
pub mod uncertainty;

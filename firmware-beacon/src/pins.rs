//! The beacon board's pin map: which GPIO of the STM32F103ZET6 (LQFP144) drives each LED,
//! and the pins the LEDs leave alone. The modulator ([`cta_core::schedule`]) knows output
//! lines only; on this board a line's bank is a GPIO port (0 = A .. 6 = G) and its bit the
//! pin number ([`BEACON_LINES`]).

use cta_core::schedule::{Line, BANKS};
use cta_core::wire::beacon::LED_COUNT;

/// GPIO ports A..G of the STM32F103ZET6 (LQFP144): the modulator's banks.
pub const PORTS: usize = 7;
const _: () = assert!(PORTS == BANKS);

/// A GPIO pin: port (0 = A .. 6 = G) and bit (0..16).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Pin {
    /// Port index, 0 = GPIOA .. 6 = GPIOG.
    pub port: u8,
    /// Pin number within the port, 0..16.
    pub bit: u8,
}

impl Pin {
    /// Pin `P<port><bit>`.
    pub const fn new(port: u8, bit: u8) -> Self {
        Pin { port, bit }
    }
    /// Port letter, `'A'..='G'`.
    pub fn port_letter(self) -> char {
        (b'A' + self.port) as char
    }
    /// The modulator's output line of this pin: bank = port, bit = pin number.
    pub const fn line(self) -> Line {
        Line::new(self.port, self.bit)
    }
}

impl core::fmt::Display for Pin {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "P{}{}", self.port_letter(), self.bit)
    }
}

/// Pins the LEDs must not use, with the reason: the RS-232 USART, the debug header
/// (SWD, and the rest of JTAG so a JTAG probe also works), the 32 kHz crystal, the
/// tamper pin (3 mA drive only) and BOOT1. The 8 MHz crystal has dedicated OSC_IN / OSC_OUT
/// pins on the LQFP144 package.
pub const RESERVED_PINS: [(Pin, &str); 11] = [
    (Pin::new(0, 9), "USART1 TX (RS-232 to the PC)"),
    (Pin::new(0, 10), "USART1 RX (RS-232 from the PC)"),
    (Pin::new(0, 13), "SWDIO / JTMS"),
    (Pin::new(0, 14), "SWCLK / JTCK"),
    (Pin::new(0, 15), "JTDI"),
    (Pin::new(1, 2), "BOOT1"),
    (Pin::new(1, 3), "JTDO / TRACESWO"),
    (Pin::new(1, 4), "NJTRST"),
    (Pin::new(2, 13), "TAMPER-RTC (3 mA drive)"),
    (Pin::new(2, 14), "OSC32_IN (32.768 kHz crystal)"),
    (Pin::new(2, 15), "OSC32_OUT (32.768 kHz crystal)"),
];

/// The one GPIO left over after the 100 LEDs and the reserved pins (PG15: spare).
pub const SPARE_PIN: Pin = Pin::new(6, 15);

/// LED id -> GPIO. LED `id = row * 10 + column` (row, column 0..10; see
/// [`cta_core::schedule::grid_position`]) takes the `id`-th free pin in port order PA0..
/// PG14, skipping [`RESERVED_PINS`]: PA0-8, PA11-12 (ids 0-10), PB0-1, PB5-15 (11-23),
/// PC0-12 (24-36), PD0-15 (37-52), PE0-15 (53-68), PF0-15 (69-84), PG0-14 (85-99).
pub const BEACON_PINS: [Pin; LED_COUNT] = beacon_pins();

/// [`BEACON_PINS`] as the modulator's output lines (what [`cta_core::schedule::Modulator`]
/// and [`cta_core::schedule::tick_cost`] take).
pub const BEACON_LINES: [Line; LED_COUNT] = {
    let mut lines = [Line::new(0, 0); LED_COUNT];
    let mut id = 0;
    while id < LED_COUNT {
        lines[id] = BEACON_PINS[id].line();
        id += 1;
    }
    lines
};

const fn is_reserved(p: Pin) -> bool {
    let mut i = 0;
    while i < RESERVED_PINS.len() {
        if RESERVED_PINS[i].0.port == p.port && RESERVED_PINS[i].0.bit == p.bit {
            return true;
        }
        i += 1;
    }
    false
}

const fn beacon_pins() -> [Pin; LED_COUNT] {
    let mut pins = [Pin::new(0, 0); LED_COUNT];
    let mut n = 0;
    let mut port = 0;
    while port < PORTS as u8 {
        let mut bit = 0;
        while bit < 16 {
            let p = Pin::new(port, bit);
            if n < LED_COUNT && !is_reserved(p) {
                pins[n] = p;
                n += 1;
            }
            bit += 1;
        }
        port += 1;
    }
    pins
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pin_map_has_100_distinct_unreserved_pins() {
        let mut seen = [[false; 16]; PORTS];
        for (p, l) in BEACON_PINS.iter().zip(BEACON_LINES) {
            assert!((p.port as usize) < PORTS && p.bit < 16, "{p}");
            assert!(!seen[p.port as usize][p.bit as usize], "{p} used twice");
            seen[p.port as usize][p.bit as usize] = true;
            assert!(RESERVED_PINS.iter().all(|(r, _)| r != p), "{p} is reserved");
            assert_ne!(*p, SPARE_PIN);
            assert_eq!((l.bank, l.bit), (p.port, p.bit));
        }
        // Every pin of the 7 ports is an LED, reserved or the spare.
        let free = PORTS * 16 - LED_COUNT - RESERVED_PINS.len();
        assert_eq!(free, 1);
        assert_eq!(BEACON_PINS[0], Pin::new(0, 0));
        assert_eq!(BEACON_PINS[9], Pin::new(0, 11));
        assert_eq!(BEACON_PINS[99], Pin::new(6, 14));
    }
}

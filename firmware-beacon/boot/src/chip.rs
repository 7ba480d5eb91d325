//! The start-up checks on the chip.

use cta_core::crystal;
use cta_core::wire::ResetCause;
use stm32f1xx_hal::pac;

/// Polls of `HSERDY` before the crystal is given up on: at the 8 MHz the chip runs at from
/// reset, about 0.2 s (a crystal starts in a few milliseconds).
const HSE_POLLS: u32 = 200_000;

/// Take the reset cause from `RCC_CSR` and clear its flags (`RMVF`) so that the next reset is
/// told apart, then start and check the crystal, logging and resetting on a dead or wrong
/// one; a crystal the RTC cannot measure is taken for 8 MHz, with a warning. Call it first in
/// `main`, with the DWT cycle counter on and the core still on the internal oscillator (the
/// reset cause comes first: the crystal check's retries are software resets).
pub fn start(rcc: &pac::RCC, pwr: &pac::PWR, rtc: &pac::RTC) -> ResetCause {
    let reset_cause = ResetCause::from_rcc_csr(rcc.csr().read().bits());
    rcc.csr().modify(|_, w| w.rmvf().set_bit());

    if !crystal_starts(rcc) {
        // Retry from reset: a crystal that is slow to start (cold) gets another chance, and
        // a probe shows this line each time.
        defmt::error!("the 8 MHz crystal (HSE) did not start within ~0.2 s: check it and its load capacitors; resetting to retry");
        reset_after_log();
    }
    // The clock tree multiplies the crystal by 9 for 72 MHz: refuse another crystal.
    match crystal_khz(rcc, pwr, rtc) {
        Some(khz) if crystal::ACCEPTED_KHZ.contains(&khz) => {
            defmt::info!("crystal (HSE): {} kHz against the internal oscillator", khz);
        }
        Some(khz) => {
            defmt::error!("the crystal (HSE) runs at ~{} kHz against the internal oscillator, not 8 MHz: this firmware needs an 8 MHz crystal (src/chip.rs); resetting", khz);
            reset_after_log();
        }
        None => defmt::warn!(
            "the crystal (HSE) could not be measured (the RTC did not count): taken for 8 MHz"
        ),
    }
    reset_cause
}

/// Start the 8 MHz crystal (HSE) and wait for it, for at most [`HSE_POLLS`] reads. The HAL's
/// `freeze` waits for it without a limit, silently; this names the fault first.
fn crystal_starts(rcc: &pac::RCC) -> bool {
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    (0..HSE_POLLS).any(|_| rcc.cr().read().hserdy().bit_is_set())
}

/// Run [`crystal::measure_khz`] on the chip (before `freeze`: the core on the HSI, the DWT
/// cycle counter on). The RTC is in the backup domain, which neither firmware uses
/// otherwise: it is reset before (so that the RTC's clock can be chosen) and after (the RTC
/// stopped again), and the backup-domain access and clocks are switched off again.
fn crystal_khz(rcc: &pac::RCC, pwr: &pac::PWR, rtc: &pac::RTC) -> Option<u32> {
    rcc.apb1enr()
        .modify(|_, w| w.pwren().set_bit().bkpen().set_bit());
    pwr.cr().modify(|_, w| w.dbp().set_bit());
    let reset_backup_domain = || {
        rcc.bdcr().modify(|_, w| w.bdrst().set_bit());
        rcc.bdcr().modify(|_, w| w.bdrst().clear_bit());
    };
    reset_backup_domain();
    rcc.bdcr().modify(|_, w| w.rtcsel().hse().rtcen().set_bit());
    // Registers read through the RTC's APB interface are valid once it has resynchronised.
    rtc.crl().modify(|_, w| w.rsf().clear_bit());
    let synced = (0..crystal::MAX_PASSES).any(|_| rtc.crl().read().rsf().bit_is_set());
    let khz = if synced {
        crystal::measure_khz(
            || rtc.divl().read().bits(),
            cortex_m::peripheral::DWT::cycle_count,
        )
    } else {
        None
    };
    reset_backup_domain();
    pwr.cr().modify(|_, w| w.dbp().clear_bit());
    rcc.apb1enr()
        .modify(|_, w| w.pwren().clear_bit().bkpen().clear_bit());
    khz
}

/// Reset after a fatal start-up log line, ~150 ms later (`delay`: 3 cycles a count on the
/// Cortex-M3, at the HSI's 8 MHz; at least 50 ms): the probe reads the RTT buffer by
/// polling, and the reset starts it afresh, so a reset at once would lose the line.
fn reset_after_log() -> ! {
    cortex_m::asm::delay(400_000);
    cortex_m::peripheral::SCB::sys_reset()
}

//! Wiring of the beacon board (STM32F103ZET6): clocks, GPIO, USART1, TIM2, IWDG and fault
//! handlers around the library's [`Board`] and [`Modulator`]. Compiled for the chip only.
//!
//! * Boot: the reset cause is read, and the 8 MHz crystal (HSE) must start and measure 8 MHz
//!   against the internal RC oscillator, or the board logs why and resets to try again (LEDs
//!   off): [`cta_firmware_boot::start`], shared with the sensor board.
//! * Boot: every LED pin is driven low before it becomes an output (the MOSFET gates are
//!   pulled down until then), so the LEDs are off from reset.
//! * TIM2 update interrupt at [`TICK_HZ`] (72 MHz / 576), highest priority: one
//!   [`Modulator::tick`], flipping LED pins through `ODR` (and `BSRR` for LEDs at several
//!   frequencies). The watchdog is fed only while its tick counter advances.
//! * USART1 (PA9 TX, PA10 RX, 115200 8N1, RS-232 transceiver) receive interrupt: bytes go
//!   into a bounded queue; the main loop feeds them to the [`Board`] and sends its replies.
//! * Independent watchdog (~0.5 s), fed by the main loop only while the tick interrupt is
//!   advancing: a stuck main loop or a dead timer resets the chip, which boots dark.
//! * HardFault (also reached by a panic: panic-probe ends in `udf`) and any unexpected
//!   interrupt: all LEDs off, then wait for the watchdog.

use core::cell::RefCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use critical_section::Mutex;
use defmt_rtt as _;
use heapless::Deque;
use panic_probe as _;
use stm32f1xx_hal::{
    pac::{self, interrupt, Interrupt},
    prelude::*,
    rcc,
    serial::{Config, Rx},
    timer::Event,
    watchdog::IndependentWatchdog,
};

use cta_core::schedule::{lost_ticks, Gpio, Modulator, NORTHSTAR_TABLE_MHZ, TICK_HZ};
use cta_core::wire::beacon::{LedMode, LED_COUNT};
use cta_core::wire::MAX_FRAME;
use cta_firmware_beacon::board::{Board, Outputs};
use cta_firmware_beacon::pins::{BEACON_LINES, BEACON_PINS, PORTS};

/// Core clock, Hz (8 MHz crystal x 9).
const SYSCLK_HZ: u32 = 72_000_000;
/// Receive queue between the USART interrupt and the main loop: bytes, and [`RX_FAULT`]
/// where the USART reported an error, so that the board drops the partial frame at the
/// point of the error (not after the bytes that followed it, which begin the next frame).
const RX_QUEUE: usize = 512;
const RX_FAULT: u16 = 0x100;
/// Queued bytes handled per main-loop pass (at most one reply is sent per pass too).
const RX_PER_PASS: usize = 64;

static MODULATOR: Mutex<RefCell<Modulator>> = Mutex::new(RefCell::new(Modulator::EMPTY));
static RX: Mutex<RefCell<Option<Rx<pac::USART1>>>> = Mutex::new(RefCell::new(None));
static RX_BYTES: Mutex<RefCell<Deque<u16, RX_QUEUE>>> = Mutex::new(RefCell::new(Deque::new()));
/// Bytes lost to a full queue (or an error marker that did not fit), not yet reported to
/// the board.
static RX_ERRORS: AtomicU32 = AtomicU32::new(0);

/// GPIO ports A..G (port index of [`cta_firmware_beacon::pins::Pin`]), padded to 8 entries so
/// that `GPIO[p & 7]` needs no bounds check in the tick interrupt (the modulator only
/// passes p < 7).
const GPIO: [*const pac::gpioa::RegisterBlock; 8] = [
    pac::GPIOA::PTR,
    pac::GPIOB::PTR,
    pac::GPIOC::PTR,
    pac::GPIOD::PTR,
    pac::GPIOE::PTR,
    pac::GPIOF::PTR,
    pac::GPIOG::PTR,
    pac::GPIOG::PTR,
];

/// `BSRR` register of GPIO port `p` (0 = A .. 6 = G).
#[inline(always)]
fn bsrr(p: usize) -> *mut u32 {
    // SAFETY: a valid peripheral register address; only written with volatile stores.
    unsafe { (*GPIO[p & 7]).bsrr().as_ptr() }
}

/// `ODR` register of GPIO port `p`.
#[inline(always)]
fn odr(p: usize) -> *mut u32 {
    // SAFETY: as for `bsrr`.
    unsafe { (*GPIO[p & 7]).odr().as_ptr() }
}

/// The GPIO ports as the modulator's output.
struct Ports;

impl Gpio for Ports {
    #[inline(always)]
    fn toggle(&mut self, port: usize, mask: u16) {
        // SAFETY: read-modify-write of ODR flipping LED pins only. Only this interrupt
        // (highest priority) and code inside a critical section touch LED-port outputs.
        unsafe {
            let r = odr(port);
            r.write_volatile(r.read_volatile() ^ mask as u32);
        }
    }
    #[inline(always)]
    fn write(&mut self, port: usize, w: u32) {
        // SAFETY: BSRR writes are atomic and the modulator only sets/resets LED pins.
        unsafe { bsrr(port).write_volatile(w) }
    }
}

/// LED pins of each port.
fn led_masks() -> [u16; PORTS] {
    let mut m = [0u16; PORTS];
    for p in BEACON_PINS {
        m[p.port as usize] |= 1 << p.bit;
    }
    m
}

/// Drive every LED pin low (usable from fault handlers: no locks, no allocation).
fn all_leds_off() {
    for (p, mask) in led_masks().iter().enumerate() {
        // SAFETY: BSRR writes are atomic and only reset LED pins.
        unsafe { bsrr(p).write_volatile((*mask as u32) << 16) };
    }
}

/// Make every LED pin a 2 MHz push-pull output, driven low first.
fn configure_led_pins() {
    all_leds_off();
    for (p, mask) in led_masks().iter().enumerate() {
        let block = GPIO[p];
        // CNF = 00 (push-pull), MODE = 10 (output, 2 MHz) in each pin's nibble.
        let (mut lo_m, mut lo_v, mut hi_m, mut hi_v) = (0u32, 0u32, 0u32, 0u32);
        for bit in 0..16 {
            if mask & (1 << bit) != 0 {
                if bit < 8 {
                    lo_m |= 0xf << (4 * bit);
                    lo_v |= 0x2 << (4 * bit);
                } else {
                    hi_m |= 0xf << (4 * (bit - 8));
                    hi_v |= 0x2 << (4 * (bit - 8));
                }
            }
        }
        // SAFETY: read-modify-write of the configuration of LED pins only, before the
        // interrupts that touch the GPIOs are enabled.
        unsafe {
            (*block)
                .crl()
                .modify(|r, w| w.bits((r.bits() & !lo_m) | lo_v));
            (*block)
                .crh()
                .modify(|r, w| w.bits((r.bits() & !hi_m) | hi_v));
        }
    }
}

/// The modulator in its static, with every port rewritten after a change.
struct ChipOutputs;

/// Cycles per tick: TIM2 counts the 72 MHz timer clock (APB1 / 2, doubled) up to 575.
const TICK_CYCLES: u32 = SYSCLK_HZ / TICK_HZ;
/// Most ticks caught up after one reconfiguration (a reconfiguration takes at most ~16).
const MAX_CATCH_UP: u32 = 64;

impl ChipOutputs {
    /// Change the modulator with the tick interrupt masked (the critical section masks
    /// every interrupt), then catch up the ticks the timer raised meanwhile beyond the one
    /// left pending ([`cta_core::schedule::lost_ticks`]: from the timer's counter and
    /// pending flag at the start and the cycles since), so that every wave keeps its phase,
    /// and drive every port to the levels.
    fn with(&mut self, f: impl FnOnce(&mut Modulator)) {
        critical_section::with(|cs| {
            // SAFETY: reads of TIM2's counter and status (the tick interrupt is masked).
            let tim = unsafe { &*pac::TIM2::ptr() };
            let start = cortex_m::peripheral::DWT::cycle_count();
            let count = tim.cnt().read().bits() & 0xffff;
            let pending = tim.sr().read().uif().bit_is_set();
            let mut m = MODULATOR.borrow_ref_mut(cs);
            f(&mut m);
            let mut caught = 0;
            while caught < MAX_CATCH_UP {
                let elapsed = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(start);
                if caught >= lost_ticks(pending, count, elapsed, TICK_CYCLES) {
                    break;
                }
                m.tick_silently();
                caught += 1;
            }
            for (p, w) in m.all_bsrr().iter().enumerate() {
                // SAFETY: BSRR write of LED pins only.
                unsafe { bsrr(p).write_volatile(*w) };
            }
        });
    }
}

impl Outputs for ChipOutputs {
    fn set_table(&mut self, table_mhz: &[u32]) {
        self.with(|m| Outputs::set_table(m, table_mhz));
    }
    fn set_modes(&mut self, modes: &[LedMode; LED_COUNT]) {
        self.with(|m| m.configure(modes));
    }
}

/// Milliseconds since boot from the 32-bit DWT cycle counter, extended to 64 bits (the
/// main loop calls it far more often than the 59 s wrap period).
struct Clock {
    last: u32,
    cycles: u64,
}

impl Clock {
    fn now_ms(&mut self) -> u64 {
        let c = cortex_m::peripheral::DWT::cycle_count();
        self.cycles += c.wrapping_sub(self.last) as u64;
        self.last = c;
        self.cycles / (SYSCLK_HZ as u64 / 1000)
    }
}

#[entry]
fn main() -> ! {
    let dp = pac::Peripherals::take().unwrap();
    let mut cp = cortex_m::Peripherals::take().unwrap();
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    // What reset the chip, then the crystal (before the clock tree below, which multiplies
    // it by 9 for 72 MHz).
    let reset_cause = cta_firmware_boot::start(&dp.RCC, &dp.PWR, &dp.RTC);
    let mut flash = dp.FLASH.constrain();
    let mut rcc = dp.RCC.freeze(
        rcc::Config::hse(8.MHz())
            .sysclk(SYSCLK_HZ.Hz())
            .pclk1(36.MHz()),
        &mut flash.acr,
    );

    // GPIO clocks (split enables and resets each port), LED pins low, then outputs.
    let mut gpioa = dp.GPIOA.split(&mut rcc);
    let _ = (
        dp.GPIOB.split(&mut rcc),
        dp.GPIOC.split(&mut rcc),
        dp.GPIOD.split(&mut rcc),
        dp.GPIOE.split(&mut rcc),
        dp.GPIOF.split(&mut rcc),
        dp.GPIOG.split(&mut rcc),
    );
    configure_led_pins();

    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.start(500.millis());

    // RS-232 link.
    let tx_pin = gpioa.pa9.into_alternate_push_pull(&mut gpioa.crh);
    let rx_pin = gpioa.pa10;
    let serial = dp.USART1.serial(
        (tx_pin, rx_pin),
        Config::default().baudrate(115_200.bps()),
        &mut rcc,
    );
    let (mut tx, mut rx) = serial.split();
    rx.listen();
    critical_section::with(|cs| RX.borrow(cs).replace(Some(rx)));

    // Modulator and board, all LEDs off.
    // In place: the modulator is too large for a temporary on the stack.
    let loaded = critical_section::with(|cs| {
        MODULATOR
            .borrow_ref_mut(cs)
            .load(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES)
    });
    if loaded.is_err() {
        panic!("default table rejected");
    }
    let mut out = ChipOutputs;
    static mut BOARD: MaybeUninit<Board> = MaybeUninit::uninit();
    // SAFETY: main runs once and is the only user of BOARD.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(BOARD) };
    let board = Board::init(slot, false, reset_cause);
    board.start(&mut out);

    // Tick timer: TIM2 at exactly TICK_HZ.
    let mut timer = dp.TIM2.counter_hz(&mut rcc);
    unwrap_or_halt(timer.start(TICK_HZ.Hz()).is_ok());
    timer.listen(Event::Update);
    // Kept running: this function never returns, so `_tick` is never dropped.
    let _tick = timer;

    let mut clock = Clock {
        last: cortex_m::peripheral::DWT::cycle_count(),
        cycles: 0,
    };

    // SAFETY: priorities set before unmasking; the handlers only use the statics above.
    unsafe {
        cp.NVIC.set_priority(Interrupt::TIM2, 0x00);
        cp.NVIC.set_priority(Interrupt::USART1, 0x40);
        NVIC::unmask(Interrupt::TIM2);
        NVIC::unmask(Interrupt::USART1);
    }
    defmt::info!(
        "beacon board up: {} Hz tick, reset cause: {=str}",
        TICK_HZ,
        reset_cause.name()
    );

    let mut tx_buf = [0u8; MAX_FRAME];
    let ticks = || critical_section::with(|cs| MODULATOR.borrow_ref(cs).now());
    let mut last_ticks = ticks();
    loop {
        let now_ms = clock.now_ms();
        // At most RX_PER_PASS bytes and one reply per pass, so that the deadman, the
        // watchdog and the error count keep their turn however fast requests arrive (a
        // host that does not wait for replies keeps the queue from emptying, and each
        // reply takes milliseconds to send).
        for _ in 0..RX_PER_PASS {
            let Some(item) = critical_section::with(|cs| RX_BYTES.borrow_ref_mut(cs).pop_front())
            else {
                break;
            };
            let Ok(byte) = u8::try_from(item) else {
                board.uart_error();
                continue;
            };
            if let Some(frame) = board.feed(byte, now_ms, &mut out, &mut tx_buf) {
                for &b in frame {
                    let _ = nb::block!(tx.write_u8(b));
                }
                break;
            }
        }
        for _ in 0..RX_ERRORS.swap(0, Ordering::Relaxed) {
            board.uart_error();
        }
        board.poll(now_ms, &mut out);
        // Feed the watchdog only while the tick interrupt is advancing the modulator.
        let now_ticks = ticks();
        if now_ticks != last_ticks {
            last_ticks = now_ticks;
            watchdog.feed();
        }
    }
}

/// Stop here (LEDs off) if a start-up step failed; the watchdog then resets the chip.
fn unwrap_or_halt(ok: bool) {
    if !ok {
        all_leds_off();
        loop {
            cortex_m::asm::nop();
        }
    }
}

#[interrupt]
fn TIM2() {
    // SAFETY: clear the update flag (write 0 to UIF, 1 to the other rc_w0 flags).
    unsafe { (*pac::TIM2::ptr()).sr().write(|w| w.bits(!1)) };
    critical_section::with(|cs| MODULATOR.borrow_ref_mut(cs).tick(&mut Ports));
}

#[interrupt]
fn USART1() {
    critical_section::with(|cs| {
        let mut rx = RX.borrow_ref_mut(cs);
        let Some(rx) = rx.as_mut() else { return };
        let mut q = RX_BYTES.borrow_ref_mut(cs);
        // At most a few bytes per interrupt; errors are cleared by the read.
        for _ in 0..4 {
            match rx.read() {
                Ok(b) => {
                    if q.push_back(u16::from(b)).is_err() {
                        RX_ERRORS.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(_)) => {
                    if q.push_back(RX_FAULT).is_err() {
                        RX_ERRORS.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }
    });
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    all_leds_off();
    loop {
        cortex_m::asm::nop();
    }
}

#[exception]
unsafe fn DefaultHandler(_irq: i16) {
    all_leds_off();
    loop {
        cortex_m::asm::nop();
    }
}

//! Wiring of the sensor board (STM32F103C8): clocks, the two USARTs, the flash pages and
//! the watchdog around the library's [`Board`]. Compiled for the chip only.
//!
//! * USART1 (PA9 TX, PA10 RX, 115200 8N1): the PC link.
//! * USART2 (PA2 TX, PA3 RX, [`NS_BAUD`] 8N1): the NorthStar link.
//! * Both receive interrupts push bytes into bounded queues; the main loop feeds them to
//!   the board (a pose solve takes tens of milliseconds, during which bytes keep arriving
//!   into the queues instead of overrunning the USARTs).
//! * Frames to the PC go whole into a transmit queue ([`TX_QUEUE`] bytes) that the USART1
//!   interrupt empties, so a report (about 90 bytes, 8 ms at 115200 baud) is sent while
//!   the next frame is solved; a frame the queue has no room for is dropped and counted
//!   (`dropped` in the status). The few bytes of NorthStar commands are sent blocking.
//! * Flash pages 62 and 63 (the last 2 KiB of the 64 KiB) hold the A/B configuration
//!   records ([`crate::storage`]); the firmware itself is budgeted to 48 KiB.
//! * Independent watchdog (~1 s), fed by the main loop. What reset the chip (RCC_CSR's
//!   flags, [`cta_core::wire::ResetCause`]) is read at boot, then cleared, and the status reports it.
//! * Boot: the 8 MHz crystal (HSE) must start and measure 8 MHz against the internal RC
//!   oscillator, or the board logs why and resets to try again; this and the reset cause are
//!   [`cta_firmware_boot::start`], shared with the beacon board.

use core::cell::RefCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use critical_section::Mutex;
use defmt_rtt as _;
use heapless::spsc::{Consumer, Producer, Queue};
use heapless::Deque;
use panic_probe as _;
use stm32f1xx_hal::{
    flash::{FlashSize, Parts as FlashParts, SectorSize},
    pac::{self, interrupt, Interrupt},
    prelude::*,
    rcc,
    serial::{Config, Rx, Tx},
    watchdog::IndependentWatchdog,
};

use cta_firmware_sensor::board::{queue_whole, Board, Io, TX_QUEUE};
use cta_firmware_sensor::northstar::NS_BAUD;
use cta_firmware_sensor::storage::{FlashPages, StorageError, MAX_RECORD};

/// Core clock, Hz (8 MHz crystal x 9).
const SYSCLK_HZ: u32 = 72_000_000;
/// Receive queues between the USART interrupts and the main loop.
const PC_QUEUE: usize = 512;
const NS_QUEUE: usize = 512;
/// Offsets (from the start of flash) of the two configuration pages (build.rs links the
/// image below them: keep its `CONFIG_PAGES` equal to the first).
const PAGES: [u32; 2] = [62 * 1024, 63 * 1024];
const FLASH_BASE: u32 = 0x0800_0000;

static PC_RX: Mutex<RefCell<Option<Rx<pac::USART1>>>> = Mutex::new(RefCell::new(None));
static NS_RX: Mutex<RefCell<Option<Rx<pac::USART2>>>> = Mutex::new(RefCell::new(None));
static PC_BYTES: Mutex<RefCell<Deque<u8, PC_QUEUE>>> = Mutex::new(RefCell::new(Deque::new()));
static NS_BYTES: Mutex<RefCell<Deque<u8, NS_QUEUE>>> = Mutex::new(RefCell::new(Deque::new()));
/// The PC-link transmitter and the consuming end of its queue, for the USART1 interrupt.
type PcTx = (Tx<pac::USART1>, Consumer<'static, u8>);
static PC_TX: Mutex<RefCell<Option<PcTx>>> = Mutex::new(RefCell::new(None));
/// Receive errors (USART errors and queue overflows), for the debug log.
static RX_ERRORS: AtomicU32 = AtomicU32::new(0);

/// The two configuration pages through the HAL's flash writer.
struct ChipFlash {
    parts: FlashParts,
}

impl FlashPages for ChipFlash {
    fn read(&self, page: usize) -> &[u8] {
        let addr = FLASH_BASE + PAGES[page & 1];
        // SAFETY: a readable, memory-mapped flash region of MAX_RECORD bytes inside the
        // page, which only this type modifies (and not while the slice is alive: `&self`).
        unsafe { core::slice::from_raw_parts(addr as *const u8, MAX_RECORD) }
    }
    fn erase(&mut self, page: usize) -> Result<(), StorageError> {
        let mut w = self.parts.writer(SectorSize::Sz1K, FlashSize::Sz64K);
        w.page_erase(PAGES[page & 1])
            .map_err(|_| StorageError::Erase)
    }
    fn write(&mut self, page: usize, data: &[u8]) -> Result<(), StorageError> {
        let mut w = self.parts.writer(SectorSize::Sz1K, FlashSize::Sz64K);
        w.write(PAGES[page & 1], data)
            .map_err(|_| StorageError::Write)
    }
}

/// Microseconds since boot from the DWT cycle counter, extended to 64 bits. The counter
/// wraps every 59.65 s, so the main loop reads the clock on every pass (a silent link would
/// otherwise leave it unread for longer, and each wrap would be lost). Only 32-bit
/// divisions (the Cortex-M3 has them in hardware; a 64-bit division would pull in a
/// libcall).
struct Clock {
    last: u32,
    rem: u32,
    us: u64,
}

impl Clock {
    fn now_us(&mut self) -> u64 {
        const PER_US: u32 = SYSCLK_HZ / 1_000_000;
        let c = cortex_m::peripheral::DWT::cycle_count();
        let d = c.wrapping_sub(self.last) as u64 + self.rem as u64;
        self.last = c;
        // d < 2^33: split so the division stays 32-bit.
        let (hi, lo) = ((d >> 16) as u32, (d & 0xffff) as u32);
        let q_hi = hi / PER_US;
        let r = ((hi % PER_US) << 16) | lo;
        self.us += ((q_hi as u64) << 16) + (r / PER_US) as u64;
        self.rem = r % PER_US;
        self.us
    }
}

struct ChipIo {
    /// The producing end of the PC-link transmit queue.
    pc: Producer<'static, u8>,
    ns: Tx<pac::USART2>,
    clock: Clock,
}

impl Io for ChipIo {
    fn now_us(&mut self) -> u64 {
        self.clock.now_us()
    }
    fn send_pc(&mut self, bytes: &[u8]) -> bool {
        if !queue_whole(&mut self.pc, bytes) {
            return false;
        }
        // Wake the transmitter (the interrupt stops listening when the queue runs dry).
        critical_section::with(|cs| {
            if let Some((tx, _)) = PC_TX.borrow_ref_mut(cs).as_mut() {
                tx.listen();
            }
        });
        true
    }
    fn send_ns(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let _ = nb::block!(self.ns.write_u8(b));
        }
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
    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    // Halted by a debugger (a breakpoint), the chip is not reset under it.
    watchdog.stop_on_debug(&dp.DBGMCU, true);
    watchdog.start(1000.millis());

    let mut gpioa = dp.GPIOA.split(&mut rcc);
    let pc_tx = gpioa.pa9.into_alternate_push_pull(&mut gpioa.crh);
    let (pc_tx, mut pc_rx) = dp
        .USART1
        .serial(
            // Pulled up: an unplugged link idles high instead of reading noise as bytes.
            (pc_tx, gpioa.pa10.into_pull_up_input(&mut gpioa.crh)),
            Config::default().baudrate(115_200.bps()),
            &mut rcc,
        )
        .split();
    let ns_tx = gpioa.pa2.into_alternate_push_pull(&mut gpioa.crl);
    let (ns_tx, mut ns_rx) = dp
        .USART2
        .serial(
            (ns_tx, gpioa.pa3.into_pull_up_input(&mut gpioa.crl)),
            Config::default().baudrate(NS_BAUD.bps()),
            &mut rcc,
        )
        .split();
    pc_rx.listen();
    ns_rx.listen();
    static mut PC_TX_QUEUE: Queue<u8, TX_QUEUE> = Queue::new();
    // SAFETY: main runs once and is the only user of PC_TX_QUEUE: the queue is split here,
    // once, into its producer (main's) and its consumer (the interrupt's).
    let (pc_queue, pc_sender) = unsafe { (*core::ptr::addr_of_mut!(PC_TX_QUEUE)).split() };
    critical_section::with(|cs| {
        PC_RX.borrow(cs).replace(Some(pc_rx));
        NS_RX.borrow(cs).replace(Some(ns_rx));
        PC_TX.borrow(cs).replace(Some((pc_tx, pc_sender)));
    });

    let mut io = ChipIo {
        pc: pc_queue,
        ns: ns_tx,
        clock: Clock {
            last: cortex_m::peripheral::DWT::cycle_count(),
            rem: 0,
            us: 0,
        },
    };

    // The board's state (decoders, stored configuration, pose solver with its carried
    // linearisation: several KiB) lives in a static, where the linker's .bss (the static RAM
    // ci.sh reports) counts it; on main's stack it would be counted nowhere.
    static mut BOARD: MaybeUninit<Board<ChipFlash>> = MaybeUninit::uninit();
    // SAFETY: main runs once and is the only user of BOARD.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(BOARD) };
    let board = Board::init(slot, ChipFlash { parts: flash }, false, reset_cause);
    // SAFETY: the handlers only use the statics above.
    unsafe {
        cp.NVIC.set_priority(Interrupt::USART1, 0x40);
        cp.NVIC.set_priority(Interrupt::USART2, 0x40);
        NVIC::unmask(Interrupt::USART1);
        NVIC::unmask(Interrupt::USART2);
    }
    board.start(&mut io);
    defmt::info!("sensor board up, reset cause: {=str}", reset_cause.name());

    let mut pc = [0u8; 64];
    let mut ns = [0u8; 64];
    loop {
        let n = drain(&PC_BYTES, &mut pc);
        let k = drain(&NS_BYTES, &mut ns);
        // The board's work (and its stack, measured in QEMU) is all below this call.
        board.poll(&pc[..n], &ns[..k], &mut io);
        // At least once per pass, so that no 59.65 s wrap of the cycle counter is missed.
        io.clock.now_us();
        let errors = RX_ERRORS.swap(0, Ordering::Relaxed);
        if errors != 0 {
            defmt::warn!("{} receive errors", errors);
        }
        watchdog.feed();
    }
}

/// Move up to `out.len()` queued bytes into `out`.
fn drain<const N: usize>(q: &Mutex<RefCell<Deque<u8, N>>>, out: &mut [u8]) -> usize {
    critical_section::with(|cs| {
        let mut q = q.borrow_ref_mut(cs);
        let mut n = 0;
        while n < out.len() {
            match q.pop_front() {
                Some(b) => {
                    out[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    })
}

fn receive<U, const N: usize>(rx: &Mutex<RefCell<Option<Rx<U>>>>, q: &Mutex<RefCell<Deque<u8, N>>>)
where
    U: stm32f1xx_hal::serial::Instance,
{
    critical_section::with(|cs| {
        let mut rx = rx.borrow_ref_mut(cs);
        let Some(rx) = rx.as_mut() else { return };
        let mut q = q.borrow_ref_mut(cs);
        for _ in 0..4 {
            match rx.read() {
                Ok(b) => {
                    if q.push_back(b).is_err() {
                        RX_ERRORS.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(_)) => {
                    RX_ERRORS.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    });
}

/// Move queued bytes into the PC USART while it can take them; stop listening for "transmit
/// register empty" once the queue is dry (`send_pc` listens again after queueing a frame).
fn transmit() {
    critical_section::with(|cs| {
        let mut tx = PC_TX.borrow_ref_mut(cs);
        let Some((tx, queue)) = tx.as_mut() else {
            return;
        };
        while tx.is_tx_empty() {
            match queue.dequeue() {
                Some(b) => {
                    let _ = tx.write_u8(b);
                }
                None => {
                    tx.unlisten();
                    break;
                }
            }
        }
    });
}

#[interrupt]
fn USART1() {
    receive(&PC_RX, &PC_BYTES);
    transmit();
}

#[interrupt]
fn USART2() {
    receive(&NS_RX, &NS_BYTES);
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    loop {
        cortex_m::asm::nop();
    }
}

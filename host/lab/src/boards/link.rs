//! Request/response client for the boards' serial links, generic over the board's
//! [`Protocol`] (the beacon board's [`cta_core::wire::beacon::Beacon`], the sensor board's
//! protocol) and over the port (any `Read + Write`: a real serial port, the pseudo-terminal
//! of a simulated board, an in-memory pipe in tests).
//!
//! Every request gets a fresh sequence number (1..=65535, skipping [`SEQ_NONE`]; each link
//! starts at a random one, so a late reply meant for an earlier process or connection on the
//! same port cannot pass for the answer to a new request), is framed by [`encode_frame`] and
//! answered by the board with the same sequence number. [`Link`]
//! waits for that reply up to [`LinkConfig::timeout`], ignoring stale replies (other sequence
//! numbers), corrupted frames and the board's answers to line garbage ([`SEQ_NONE`]), and
//! resends (with a new sequence number) up to [`LinkConfig::retries`] times. All the boards'
//! requests are idempotent (they set state), so a resend after a lost reply is harmless.
//! Refusals come back as typed errors: [`LinkError::Refused`] with the board's own error
//! type, [`LinkError::BadFrame`] when the board could not decode the request.
//!
//! Nothing read is lost: bytes that arrive after a reply in the same read stay for the next
//! call, and the board's unsolicited reports ([`SEQ_NONE`], e.g. the sensor board's stream)
//! that arrive while a reply is awaited are queued (up to [`UNSOLICITED_QUEUE`]) for
//! [`Link::next_unsolicited`].

use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read, Write};
use std::marker::PhantomData;
use std::time::{Duration, Instant};

use cta_core::wire::{
    encode_frame, BoardKind, EncodeError, ErrorReply, FrameDecoder, FrameFault, Header, Identity,
    Protocol, Reply, Request, Response, MAX_FRAME, PROTOCOL_VERSION, SEQ_NONE,
};
use serde::{Deserialize, Serialize};

/// Unsolicited reports kept while a reply is awaited; older ones are dropped (and counted in
/// [`LinkStats::dropped_reports`]) beyond this.
pub const UNSOLICITED_QUEUE: usize = 1024;

/// Baud rate of both boards' host links (115200 8N1).
pub const BAUD: u32 = 115_200;

/// Timing of a [`Link`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkConfig {
    /// How long to wait for the reply to one attempt.
    pub timeout: Duration,
    /// Resends after the first attempt.
    pub retries: u32,
}

impl Default for LinkConfig {
    /// 500 ms per attempt (the largest frame takes ~90 ms each way at 115200 baud), 2
    /// resends.
    fn default() -> Self {
        LinkConfig {
            timeout: Duration::from_millis(500),
            retries: 2,
        }
    }
}

/// Counters of a [`Link`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Requests sent (resends included).
    pub sent: u64,
    /// Resends after a timeout.
    pub resent: u64,
    /// Replies with another sequence number (late replies to earlier attempts).
    pub stale: u64,
    /// Reply frames that could not be decoded.
    pub corrupted: u64,
    /// Board answers to frames it could not read (line garbage, or a corrupted request).
    pub garbage_answers: u64,
    /// Unsolicited reports dropped because [`UNSOLICITED_QUEUE`] was full.
    pub dropped_reports: u64,
}

/// What went wrong with a request.
#[derive(Debug, thiserror::Error)]
pub enum LinkError<E: fmt::Debug + fmt::Display> {
    /// The port failed (unplugged, closed, a simulated board stopped). The message includes
    /// the port's error, which is therefore not also given as its source: `{:#}` would print
    /// it twice.
    #[error("port lost: {0}")]
    Io(io::Error),
    /// No reply.
    #[error("no reply from the board after {attempts} attempt(s) of {timeout:?} each (is it powered, on this port, at {BAUD} baud?)")]
    Timeout {
        /// Attempts made.
        attempts: u32,
        /// Wait per attempt.
        timeout: Duration,
    },
    /// The board could not decode the request frame.
    #[error("the board rejected request #{seq}: {fault}")]
    BadFrame {
        /// Sequence number of the request.
        seq: u16,
        /// What the board found wrong.
        fault: FrameFault,
    },
    /// The board understood the request and refused it.
    #[error("the board refused request #{seq}: {error}")]
    Refused {
        /// Sequence number of the request.
        seq: u16,
        /// The board's reason.
        error: E,
    },
    /// The request does not fit a frame.
    #[error("the request cannot be framed: {0}")]
    Encode(EncodeError),
    /// A well-formed reply of the wrong kind.
    #[error("unexpected reply to {request}: {reply}")]
    Unexpected {
        /// The request.
        request: String,
        /// The reply.
        reply: String,
    },
    /// Another board (or protocol version) answered. When it is the other kind of board, the
    /// message suggests the beacon and sensor ports may be swapped.
    #[error("expected a {expected} board speaking protocol {PROTOCOL_VERSION}, but a {} board speaking protocol {} answered{}", got.board, got.protocol, swapped_hint(*expected, got.board))]
    WrongBoard {
        /// The board expected.
        expected: BoardKind,
        /// Who answered.
        got: Identity,
    },
}

impl<E: fmt::Debug + fmt::Display> From<io::Error> for LinkError<E> {
    fn from(e: io::Error) -> Self {
        LinkError::Io(e)
    }
}

/// After [`LinkError::WrongBoard`]'s message: when the `got` board answered where the
/// `expected` one should be, the two boards' ports are probably the other way round.
fn swapped_hint(expected: BoardKind, got: BoardKind) -> String {
    if expected == got {
        return String::new();
    }
    format!(" (is this the {got} board's port? the beacon and sensor ports may be swapped)")
}

/// Request/response client for the board of protocol `P` over port `S`.
pub struct Link<P: Protocol, S> {
    port: S,
    config: LinkConfig,
    seq: u16,
    decoder: FrameDecoder<MAX_FRAME>,
    stats: LinkStats,
    /// Bytes read but not decoded yet (they followed a reply in the same read).
    pending: VecDeque<u8>,
    /// Unsolicited reports received while a reply was awaited.
    unsolicited: VecDeque<Response<P::Response>>,
    _protocol: PhantomData<P>,
}

/// Result of a [`Link`] request.
pub type LinkResult<T, P> = Result<T, LinkError<<P as Protocol>::Error>>;

impl<P: Protocol, S: Read + Write> Link<P, S> {
    /// Client over `port`. Reads on `port` should time out after a short while (a few ms;
    /// [`open_serial`] sets 10 ms) so the link can keep its own deadlines. The first request
    /// gets a random sequence number (the boards echo whatever they are sent): replies still
    /// on their way to an earlier link on the same port (another process, or this one before
    /// a reconnection) then match a new request only by a 1 in 65535 chance.
    pub fn new(port: S, config: LinkConfig) -> Self {
        Link {
            port,
            config,
            // next_seq() steps past it before the first request.
            seq: rand::random(),
            decoder: FrameDecoder::new(),
            stats: LinkStats::default(),
            pending: VecDeque::new(),
            unsolicited: VecDeque::new(),
            _protocol: PhantomData,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The port.
    pub fn port_mut(&mut self) -> &mut S {
        &mut self.port
    }

    fn next_seq(&mut self) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        if self.seq == SEQ_NONE {
            self.seq = 1;
        }
        self.seq
    }

    /// Send `request` and return the board's response (retrying on timeouts).
    pub fn request(
        &mut self,
        request: &Request<P::Request>,
    ) -> LinkResult<Response<P::Response>, P> {
        let attempts = self.config.retries + 1;
        let mut buf = [0u8; MAX_FRAME];
        for attempt in 0..attempts {
            let seq = self.next_seq();
            let frame =
                encode_frame(Header::new(seq), request, &mut buf).map_err(LinkError::Encode)?;
            self.port.write_all(frame)?;
            self.port.flush()?;
            self.stats.sent += 1;
            if attempt > 0 {
                self.stats.resent += 1;
            }
            if let Some(reply) = self.wait(seq)? {
                return match reply {
                    Ok(r) => Ok(r),
                    Err(ErrorReply::Board(error)) => Err(LinkError::Refused { seq, error }),
                    Err(ErrorReply::BadFrame(fault)) => Err(LinkError::BadFrame { seq, fault }),
                };
            }
        }
        Err(LinkError::Timeout {
            attempts,
            timeout: self.config.timeout,
        })
    }

    /// Read until the reply numbered `seq` arrives or the attempt times out.
    fn wait(&mut self, seq: u16) -> io::Result<Option<Reply<P::Response, P::Error>>> {
        let deadline = Instant::now() + self.config.timeout;
        self.next_frame(deadline, |h, _| h.seq == seq)
    }

    /// The next unsolicited report of the board (frames numbered [`SEQ_NONE`], e.g. the
    /// sensor board's spot and pose stream), waiting up to `timeout`; queued reports first.
    pub fn next_unsolicited(
        &mut self,
        timeout: Duration,
    ) -> io::Result<Option<Response<P::Response>>> {
        if let Some(r) = self.unsolicited.pop_front() {
            return Ok(Some(r));
        }
        let deadline = Instant::now() + timeout;
        let got = self.next_frame(deadline, |h, r| h.seq == SEQ_NONE && r.is_ok())?;
        Ok(got
            .and_then(|r| r.ok())
            .or_else(|| self.unsolicited.pop_front()))
    }

    /// Drop the queued unsolicited reports (those that arrived before the last reply, e.g.
    /// a stream that the request just changed). Bytes after the reply are kept. Returns how
    /// many were dropped.
    pub fn discard_unsolicited(&mut self) -> usize {
        let n = self.unsolicited.len();
        self.unsolicited.clear();
        n
    }

    /// Decode (pending bytes first, then reads) until a frame satisfies `want` or the
    /// deadline passes; bytes after that frame stay pending. Other frames: unsolicited
    /// reports are queued, the rest counted.
    fn next_frame(
        &mut self,
        deadline: Instant,
        want: impl Fn(&Header, &Reply<P::Response, P::Error>) -> bool,
    ) -> io::Result<Option<Reply<P::Response, P::Error>>> {
        let mut buf = [0u8; 256];
        loop {
            while let Some(b) = self.pending.pop_front() {
                match self.decoder.push::<Reply<P::Response, P::Error>>(b) {
                    None => {}
                    Some(Ok((h, reply))) if want(&h, &reply) => return Ok(Some(reply)),
                    Some(Ok((h, Ok(r)))) if h.seq == SEQ_NONE => {
                        if self.unsolicited.len() >= UNSOLICITED_QUEUE {
                            self.unsolicited.pop_front();
                            self.stats.dropped_reports += 1;
                        }
                        self.unsolicited.push_back(r);
                    }
                    Some(Ok((h, Err(_)))) if h.seq == SEQ_NONE => self.stats.garbage_answers += 1,
                    Some(Ok(_)) => self.stats.stale += 1,
                    Some(Err(_)) => self.stats.corrupted += 1,
                }
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            let n = match self.port.read(&mut buf) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut
                            | io::ErrorKind::WouldBlock
                            | io::ErrorKind::Interrupted
                    ) =>
                {
                    0
                }
                Err(e) => return Err(e),
            };
            if n == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
            self.pending.extend(&buf[..n]);
        }
    }

    /// Send a board-specific request; `None` for a plain acknowledgement.
    pub fn call(&mut self, request: P::Request) -> LinkResult<Option<P::Response>, P> {
        let what = format!("{request:?}");
        match self.request(&Request::Board(request))? {
            Response::Ack => Ok(None),
            Response::Board(r) => Ok(Some(r)),
            other => Err(LinkError::Unexpected {
                request: what,
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Ask the board who it is.
    pub fn identify(&mut self) -> LinkResult<Identity, P> {
        match self.request(&Request::Identify)? {
            Response::Identity(id) => Ok(id),
            other => Err(LinkError::Unexpected {
                request: "Identify".into(),
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Identify and check that the board is of kind `P::BOARD` and speaks our protocol.
    pub fn check_board(&mut self) -> LinkResult<Identity, P> {
        let id = self.identify()?;
        if id.board != P::BOARD || id.protocol != PROTOCOL_VERSION {
            return Err(LinkError::WrongBoard {
                expected: P::BOARD,
                got: id,
            });
        }
        Ok(id)
    }

    /// Keep the board's dead-man timer from expiring.
    pub fn heartbeat(&mut self) -> LinkResult<(), P> {
        match self.request(&Request::Heartbeat)? {
            Response::Ack => Ok(()),
            other => Err(LinkError::Unexpected {
                request: "Heartbeat".into(),
                reply: format!("{other:?}"),
            }),
        }
    }
}

/// A message type with no values: the board messages of [`AnyBoard`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Never {}

impl fmt::Display for Never {
    fn fmt(&self, _: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {}
    }
}

/// A board of unknown kind: enough to [`Link::identify`] it (the identify request and reply
/// are the same for every board).
#[derive(Debug, Clone, Copy)]
pub struct AnyBoard;

impl Protocol for AnyBoard {
    const BOARD: BoardKind = BoardKind::Beacon;
    type Request = Never;
    type Response = Never;
    type Error = Never;
}

/// Where a one-shot command finds its board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BoardAt {
    /// A serial port: a real board, or the pseudo-terminal of a simulated one.
    Port(String),
    /// A simulated board started in this process for the one command.
    InProcess,
}

/// Open a board's serial port (115200 8N1, 10 ms read timeout), discarding whatever input was
/// already waiting on it: replies to an earlier process or connection (a command that timed
/// out, a sweep's link before it reconnected) must not be taken for answers to this one's
/// requests. What still arrives later is told apart by its sequence number ([`Link::new`]).
pub fn open_serial(path: &str) -> io::Result<Box<dyn serialport::SerialPort>> {
    let port = serialport::new(path, BAUD)
        .timeout(Duration::from_millis(10))
        .open()
        .map_err(|e| io::Error::other(format!("cannot open serial port {path}: {e}")))?;
    port.clear(serialport::ClearBuffer::Input).map_err(|e| {
        io::Error::other(format!(
            "cannot discard the waiting input of serial port {path}: {e}"
        ))
    })?;
    Ok(port)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cta_core::wire::beacon::{Beacon, BeaconError, BeaconRequest, BeaconResponse};

    /// A scripted board: answers each request frame with the reply produced by `answer`.
    struct Scripted<F> {
        rx: FrameDecoder<MAX_FRAME>,
        out: VecDeque<u8>,
        answer: F,
        requests: u32,
    }

    impl<F: FnMut(u32, Header) -> Option<Vec<u8>>> Write for Scripted<F> {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            for &b in buf {
                if let Some(Ok((h, _))) = self.rx.push::<Request<BeaconRequest>>(b) {
                    self.requests += 1;
                    if let Some(bytes) = (self.answer)(self.requests, h) {
                        self.out.extend(bytes);
                    }
                }
            }
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl<F> Read for Scripted<F> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = buf.len().min(self.out.len());
            for b in buf.iter_mut().take(n) {
                *b = self.out.pop_front().unwrap();
            }
            if n == 0 {
                return Err(io::ErrorKind::TimedOut.into());
            }
            Ok(n)
        }
    }

    fn frame(seq: u16, reply: &Reply<BeaconResponse, BeaconError>) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        encode_frame(Header::new(seq), reply, &mut buf)
            .unwrap()
            .to_vec()
    }

    fn link<F: FnMut(u32, Header) -> Option<Vec<u8>>>(answer: F) -> Link<Beacon, Scripted<F>> {
        let port = Scripted {
            rx: FrameDecoder::new(),
            out: VecDeque::new(),
            answer,
            requests: 0,
        };
        Link::new(
            port,
            LinkConfig {
                timeout: Duration::from_millis(30),
                retries: 2,
            },
        )
    }

    #[test]
    fn stale_and_garbage_replies_are_skipped() {
        let mut l = link(|_, h| {
            let mut v = frame(h.seq + 100, &Ok(Response::Ack));
            v.extend([0x13, 0x37, 0]);
            v.extend(frame(SEQ_NONE, &Err(ErrorReply::BadFrame(FrameFault::Crc))));
            v.extend(frame(h.seq, &Ok(Response::Ack)));
            Some(v)
        });
        l.heartbeat().unwrap();
        let s = l.stats();
        assert_eq!(
            (s.sent, s.stale, s.corrupted, s.garbage_answers),
            (1, 1, 1, 1)
        );
    }

    #[test]
    fn unsolicited_reports_around_a_reply_are_kept_in_order() {
        let mut l = link(|_, h| {
            // One report before the reply and two after it, all in one read.
            let mut v = frame(SEQ_NONE, &Ok(Response::Ack));
            v.extend(frame(h.seq, &Ok(Response::Ack)));
            v.extend(frame(
                SEQ_NONE,
                &Ok(Response::Board(BeaconResponse::Table(Default::default()))),
            ));
            v.extend(frame(SEQ_NONE, &Ok(Response::Ack)));
            Some(v)
        });
        l.heartbeat().unwrap();
        let t = Duration::from_millis(20);
        assert!(matches!(
            l.next_unsolicited(t).unwrap(),
            Some(Response::Ack)
        ));
        assert!(matches!(
            l.next_unsolicited(t).unwrap(),
            Some(Response::Board(BeaconResponse::Table(_)))
        ));
        assert!(matches!(
            l.next_unsolicited(t).unwrap(),
            Some(Response::Ack)
        ));
        assert!(l.next_unsolicited(t).unwrap().is_none());
        assert_eq!(l.stats().garbage_answers + l.stats().dropped_reports, 0);
    }

    #[test]
    fn discarding_drops_only_the_reports_before_the_reply() {
        let mut l = link(|_, h| {
            let mut v = frame(SEQ_NONE, &Ok(Response::Ack));
            v.extend(frame(SEQ_NONE, &Ok(Response::Ack)));
            v.extend(frame(h.seq, &Ok(Response::Ack)));
            v.extend(frame(
                SEQ_NONE,
                &Ok(Response::Board(BeaconResponse::Table(Default::default()))),
            ));
            Some(v)
        });
        l.heartbeat().unwrap();
        assert_eq!(l.discard_unsolicited(), 2);
        let t = Duration::from_millis(20);
        assert!(matches!(
            l.next_unsolicited(t).unwrap(),
            Some(Response::Board(BeaconResponse::Table(_)))
        ));
        assert!(l.next_unsolicited(t).unwrap().is_none());
    }

    #[test]
    fn lost_replies_are_retried_then_time_out() {
        let mut l = link(|n, h| (n == 3).then(|| frame(h.seq, &Ok(Response::Ack))));
        l.heartbeat().unwrap();
        assert_eq!(l.stats().resent, 2);
        let mut l = link(|_, _| None);
        match l.heartbeat() {
            Err(LinkError::Timeout { attempts: 3, .. }) => {}
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn each_link_starts_at_its_own_sequence_number() {
        // Every link used to send #1 first: a late reply to an earlier link's #1 answered it.
        let mut first = Vec::new();
        for _ in 0..8 {
            let mut seen = Vec::new();
            let mut l = link(|_, h| {
                seen.push(h.seq);
                Some(frame(h.seq, &Ok(Response::Ack)))
            });
            l.heartbeat().unwrap();
            l.heartbeat().unwrap();
            drop(l);
            assert_ne!(seen[0], SEQ_NONE);
            assert_eq!(seen[1], if seen[0] == u16::MAX { 1 } else { seen[0] + 1 });
            first.push(seen[0]);
        }
        first.sort_unstable();
        first.dedup();
        assert!(first.len() > 1, "8 links all started at #{}", first[0]);
    }

    #[test]
    fn sequence_numbers_wrap_past_seq_none() {
        let mut seen = Vec::new();
        let mut l = link(|_, h| {
            seen.push(h.seq);
            Some(frame(h.seq, &Ok(Response::Ack)))
        });
        l.seq = u16::MAX - 2;
        for _ in 0..4 {
            l.heartbeat().unwrap();
        }
        drop(l);
        assert_eq!(seen, [u16::MAX - 1, u16::MAX, 1, 2]);
    }

    #[test]
    fn a_port_error_is_said_once() {
        // Not also the error's source: that would print it twice.
        let e: LinkError<BeaconError> = io::Error::other("Broken pipe").into();
        // As the command line prints an error: its message, then each source's.
        let mut text = e.to_string();
        let mut source = std::error::Error::source(&e);
        while let Some(s) = source {
            text += &format!(": {s}");
            source = s.source();
        }
        assert_eq!(text, "port lost: Broken pipe");
    }

    #[test]
    fn the_other_board_answering_suggests_swapped_ports() {
        let id = |board| Identity {
            board,
            protocol: PROTOCOL_VERSION,
            firmware: heapless::String::try_from("0.1.0").unwrap(),
            simulated: false,
            max_frame: MAX_FRAME as u16,
        };
        let swapped = LinkError::<BeaconError>::WrongBoard {
            expected: BoardKind::Beacon,
            got: id(BoardKind::Sensor),
        }
        .to_string();
        assert!(
            swapped.contains("a sensor board speaking protocol")
                && swapped.contains("is this the sensor board's port?")
                && swapped.contains("ports may be swapped"),
            "{swapped}"
        );
        let older = LinkError::<BeaconError>::WrongBoard {
            expected: BoardKind::Beacon,
            got: Identity {
                protocol: PROTOCOL_VERSION + 1,
                ..id(BoardKind::Beacon)
            },
        }
        .to_string();
        assert!(!older.contains("swapped"), "{older}");
    }

    #[test]
    fn refusals_are_typed() {
        let mut l = link(|_, h| {
            Some(frame(
                h.seq,
                &Err(ErrorReply::Board(BeaconError::UnknownBeacon { id: 120 })),
            ))
        });
        match l.call(BeaconRequest::AllOff) {
            Err(LinkError::Refused {
                error: BeaconError::UnknownBeacon { id: 120 },
                ..
            }) => {}
            other => panic!("{other:?}"),
        }
        let msg = l.call(BeaconRequest::AllOff).unwrap_err().to_string();
        assert!(msg.contains("unknown beacon 120"), "{msg}");
    }
}

//! The follower's receiving thread: it blocks on the UDP socket and stamps each datagram with
//! the moment it was read, so that speeds measured from packet times do not depend on how often
//! the window or the recorder polls (a frame can take seconds on a CPU driver, and every packet
//! drained in one poll would otherwise carry that poll's time).

use std::io::ErrorKind;
use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Datagrams held between two polls; beyond, new ones are dropped (a flood cannot grow memory).
pub const QUEUE: usize = 4096;
/// How often the thread looks whether it should stop.
const TICK: Duration = Duration::from_millis(20);
/// The largest UDP payload: nothing is silently cut short.
const MAX_DATAGRAM: usize = 65_536;

/// One datagram and when the thread read it.
pub struct Datagram {
    pub bytes: Vec<u8>,
    pub at: Instant,
}

/// The thread and the queue it fills; dropping it stops the thread.
pub struct Receiving {
    rx: Receiver<Datagram>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Receiving {
    /// Start reading `socket` on a thread of its own.
    pub fn start(socket: UdpSocket) -> std::io::Result<Receiving> {
        socket.set_nonblocking(false)?;
        socket.set_read_timeout(Some(TICK))?;
        let (tx, rx) = sync_channel(QUEUE);
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("stratus-follow".into())
            .spawn(move || {
                let mut buf = vec![0u8; MAX_DATAGRAM];
                while !flag.load(Ordering::Relaxed) {
                    match socket.recv_from(&mut buf) {
                        Ok((n, _)) => {
                            let d = Datagram {
                                bytes: buf[..n].to_vec(),
                                at: Instant::now(),
                            };
                            if let Err(TrySendError::Disconnected(_)) = tx.try_send(d) {
                                return;
                            }
                        }
                        Err(e)
                            if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                        // ICMP echoes and the like: nothing to read; no busy loop on a lasting one.
                        Err(_) => std::thread::sleep(Duration::from_millis(1)),
                    }
                }
            })?;
        Ok(Receiving {
            rx,
            stop,
            thread: Some(thread),
        })
    }

    /// The oldest datagram not yet taken, if any (never waits).
    pub fn next(&self) -> Option<Datagram> {
        self.rx.try_recv().ok()
    }
}

impl Drop for Receiving {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

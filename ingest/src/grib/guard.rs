//! Containment of the decoder's panics. gribberish 1.9 can panic on corrupted data sections;
//! [`contained`] runs it under `catch_unwind` and a process-wide panic hook keeps such a
//! contained panic quiet (no "thread panicked" line on stderr), deferring to the previous hook
//! for every other panic.

use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Once;

thread_local! {
    static IN_DECODER: Cell<bool> = const { Cell::new(false) };
}

/// Install (once) the hook that stays quiet for panics inside [`contained`].
fn quiet_decoder_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |p| {
            if !IN_DECODER.with(|f| f.get()) {
                prev(p)
            }
        }));
    });
}

/// Run `f` (a call into the decoder); `None` if it panicked.
pub(super) fn contained<T>(f: impl FnOnce() -> T) -> Option<T> {
    quiet_decoder_panics();
    IN_DECODER.with(|c| c.set(true));
    // The closure only reads a byte slice it was given; nothing it touches outlives it.
    let r = catch_unwind(AssertUnwindSafe(f));
    IN_DECODER.with(|c| c.set(false));
    r.ok()
}

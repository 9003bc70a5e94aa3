//! Work the host hands to scoped threads.

use std::thread::ScopedJoinHandle;

/// What a scoped thread made; a panic there goes on in the caller, as if
/// the work had been done there.
pub fn join<T>(handle: ScopedJoinHandle<'_, T>) -> T {
    handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

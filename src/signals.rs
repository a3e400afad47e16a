//! SIGINT and SIGTERM end the program without leaving a temporary file or
//! folder behind (SPEC.md section 15): both signals are blocked in every
//! thread (threads inherit the mask; child processes get an empty one from
//! `std::process::Command`) and one thread waits for them, removes what
//! `golden::output` has registered, and ends the process by the same
//! signal, as if it had not been caught.

use std::sync::OnceLock;

fn termination_set() -> libc::sigset_t {
    // SAFETY: sigemptyset and sigaddset initialise and fill a local set.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        libc::sigaddset(&mut set, libc::SIGINT);
        libc::sigaddset(&mut set, libc::SIGTERM);
        set
    }
}

/// Starts the waiting thread; call once, before any other thread starts.
pub fn install() {
    static STARTED: OnceLock<()> = OnceLock::new();
    STARTED.get_or_init(|| {
        let set = termination_set();
        // SAFETY: blocks two signals in this (the main) thread before any other exists.
        unsafe {
            libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut());
        }
        std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                let mut sig: libc::c_int = 0;
                // SAFETY: sigwait fills `sig` from the blocked set.
                while unsafe { libc::sigwait(&set, &mut sig) } != 0 {}
                golden::output::remove_temporaries();
                // SAFETY: restores the default action and delivers the signal
                // to this thread, which ends the process as the signal does.
                unsafe {
                    libc::signal(sig, libc::SIG_DFL);
                    libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
                    libc::raise(sig);
                }
                std::process::exit(128 + sig);
            })
            .expect("the signal thread starts");
    });
}

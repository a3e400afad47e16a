//! Co-simulation harness (see issue 6).

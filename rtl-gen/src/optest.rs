//! Operator test modules.

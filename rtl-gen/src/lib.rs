//! rtl-gen: an embedded DSL for synthesizable RTL (see issue 4).

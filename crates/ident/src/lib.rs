//! harmonid-ident (work in progress).

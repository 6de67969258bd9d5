//! File formats read and written by the desktop tools (design §5).

//! End-to-end and traceability tests for VTSM live in `tests/tests/`.

//! Host tests of the C interface: the generated code table, the storage
//! constants, and the checks at the boundary. The C programs in `tests/ffi/`
//! exercise the same functions from C, on the host and on the Cortex-M7.

use super::*;
use std::fmt::Write as _;

/// The text of `src/codes.rs`, generated from `FailureCode::ALL`.
fn codes_rs() -> String {
    let mut s = String::new();
    s.push_str(
        "// Generated from `vtsm_core::FailureCode::ALL` by\n\
         // `VTSM_FFI_BLESS=1 cargo test -p vtsm-ffi -- codes_rs`; do not edit by hand.\n\
         // The test `codes_rs_is_generated_from_the_core_table` checks it.\n\n\
         use core::ffi::CStr;\n\n\
         /// The failure codes (the core's `FailureCode` table, and 0 for none):\n\
         /// `#[repr(u16)]`, grouped by subsystem in the high byte (0x01 config,\n\
         /// 0x02 image, 0x03 map, 0x04 raster, 0x05 ncc, 0x06 stereo, 0x07 pose,\n\
         /// 0x08 reloc, 0x09 hardware, 0x0A C interface). Every function of the\n\
         /// interface that can fail returns one as a `uint16_t`;\n\
         /// `vtsm_failure_name` gives its name. Severity, retry hint and the\n\
         /// list are in `fsw-docs/failure-codes.md`.\n\
         #[repr(u16)]\n\
         #[allow(non_camel_case_types)]\n\
         #[derive(Clone, Copy, Debug, PartialEq, Eq)]\n\
         pub enum VtsmFailure {\n    /// No failure.\n    VTSM_OK = 0,\n",
    );
    for &c in FailureCode::ALL {
        writeln!(s, "    /// {}", c.description()).unwrap();
        writeln!(s, "    VTSM_{} = 0x{:04X},", c.name(), c.code()).unwrap();
    }
    s.push_str("}\n\n/// The NUL-terminated name of a raw code.\npub(crate) fn c_name(code: u16) -> &'static CStr {\n    match code {\n        0 => c\"OK\",\n");
    for &c in FailureCode::ALL {
        writeln!(s, "        0x{:04X} => c\"{}\",", c.code(), c.name()).unwrap();
    }
    s.push_str("        _ => c\"UNKNOWN\",\n    }\n}\n");
    s
}

#[test]
fn codes_rs_is_generated_from_the_core_table() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/codes.rs");
    let want = codes_rs();
    if std::env::var_os("VTSM_FFI_BLESS").is_some() {
        std::fs::write(path, &want).unwrap();
    }
    let have = std::fs::read_to_string(path).unwrap();
    assert!(
        have == want,
        "src/codes.rs differs from the core's FailureCode table: regenerate with \
         `VTSM_FFI_BLESS=1 cargo test -p vtsm-ffi -- codes_rs`"
    );
}

#[test]
fn failure_names_match_the_core_table() {
    for &c in FailureCode::ALL {
        // SAFETY: `vtsm_failure_name` returns a static NUL-terminated string.
        let name = unsafe { core::ffi::CStr::from_ptr(vtsm_failure_name(c.code())) };
        assert_eq!(name.to_str().unwrap(), c.name());
    }
    // SAFETY: as above.
    let ok = unsafe { core::ffi::CStr::from_ptr(vtsm_failure_name(0)) };
    assert_eq!(ok.to_str().unwrap(), "OK");
    // SAFETY: as above.
    let unknown = unsafe { core::ffi::CStr::from_ptr(vtsm_failure_name(0xFFFF)) };
    assert_eq!(unknown.to_str().unwrap(), "UNKNOWN");
}

fn profile(p: VtsmProfile) -> VtsmParams {
    let mut out = VtsmParams::from_params(&Params::paper());
    // SAFETY: `out` is a live, aligned VtsmParams.
    assert_eq!(unsafe { vtsm_params_for_profile(p as u32, &mut out) }, 0);
    out
}

#[test]
fn storage_constants_are_the_computed_sizes() {
    let mut wrong = Vec::new();
    for (p, bytes) in [
        (VtsmProfile::VTSM_PROFILE_PAPER, VTSM_STORAGE_BYTES_PAPER),
        (VtsmProfile::VTSM_PROFILE_DEMO, VTSM_STORAGE_BYTES_DEMO),
        (VtsmProfile::VTSM_PROFILE_TEST, VTSM_STORAGE_BYTES_TEST),
    ] {
        let params = profile(p);
        // SAFETY: a live VtsmParams.
        let size = unsafe { vtsm_storage_size(&params) };
        if size != bytes {
            wrong.push(format!("{p:?}: constant {bytes}, computed {size}"));
        }
    }
    assert!(wrong.is_empty(), "{wrong:?}");
}

#[test]
fn params_round_trip_and_flags_are_checked() {
    let p = profile(VtsmProfile::VTSM_PROFILE_TEST);
    assert_eq!(p.to_params().unwrap(), Params::for_image_width(480));
    let mut bad = p;
    bad.reuse = 2;
    assert_eq!(bad.to_params(), Err(FailureCode::ConfigParamOutOfRange));
    let mut bad = p;
    bad.n_corr = 1;
    assert_eq!(bad.to_params(), Err(FailureCode::ConfigParamOutOfRange));
    // SAFETY: a live VtsmParams.
    assert_eq!(unsafe { vtsm_storage_size(&bad) }, 0);
    // SAFETY: null is allowed and answers 0.
    assert_eq!(unsafe { vtsm_storage_size(core::ptr::null()) }, 0);
    let mut out = p;
    // SAFETY: a live VtsmParams; profile 99 does not exist.
    let code = unsafe { vtsm_params_for_profile(99, &mut out) };
    assert_eq!(code, FailureCode::ConfigParamOutOfRange.code());
    // SAFETY: null is checked.
    let code = unsafe { vtsm_params_for_profile(3, core::ptr::null_mut()) };
    assert_eq!(code, FailureCode::FfiNullPointer.code());
}

#[test]
fn run_rejects_bad_handles() {
    let mut out = VtsmOutcome::failed(0);
    // SAFETY: null handle and limits are checked.
    let code = unsafe { vtsm_engine_run(core::ptr::null_mut(), core::ptr::null(), &mut out) };
    assert_eq!(code, FailureCode::FfiNullPointer.code());
    assert_eq!(out.failure, code);
    #[repr(C, align(16))]
    struct Zeroed([u8; 2048]);
    let mut storage = Zeroed([0; 2048]);
    let handle = storage.0.as_mut_ptr().cast::<VtsmEngine>();
    // SAFETY: a zeroed, aligned storage of 2048 bytes: no engine in it.
    let code = unsafe { vtsm_engine_run(handle, core::ptr::null(), &mut out) };
    assert_eq!(code, FailureCode::FfiBadHandle.code());
    // SAFETY: one byte off: misaligned.
    let code = unsafe {
        vtsm_engine_run(
            handle.cast::<u8>().add(1).cast(),
            core::ptr::null(),
            &mut out,
        )
    };
    assert_eq!(code, FailureCode::FfiMisaligned.code());
}

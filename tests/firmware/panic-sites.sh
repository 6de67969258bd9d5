#!/usr/bin/env bash
# Lists the panic call sites left in a firmware image, each with its inlined
# call chain, from a normal (not panic-check) release build:
#   tests/firmware/panic-sites.sh thumbv7em-none-eabihf
# Needs llvm-objdump (rustup component llvm-tools, or the system's) and llvm-addr2line or a
# multi-target addr2line.
set -eu
cd "$(dirname "$0")"
t="${1:?target triple}"
extra=()
case "$t" in
    # No prebuilt rust-std for this target: core from rust-src, as .ci/run builds it.
    armv8r-*) export RUSTC_BOOTSTRAP=1
        extra=(-Zbuild-std=core --config 'profile.release.package.core.overflow-checks=false') ;;
esac
cargo build --release --target "$t" "${extra[@]}" >&2
elf="target/$t/release/vtsm-firmware"
sysroot=$(rustc --print sysroot)
objdump=$(find "$sysroot" -name llvm-objdump -type f | head -n 1)
objdump=${objdump:-$(command -v llvm-objdump)}
a2l=$(command -v llvm-addr2line || command -v addr2line)
"$objdump" -d --no-show-raw-insn -C "$elf" \
    | grep -E '<core::(panicking|slice::(index|copy_from_slice_impl)|option::|result::|cell::panic|str::slice_error)' \
    | grep -vE '^[0-9a-f]+ <' | awk '{print $1}' | tr -d ':' | while read -r a; do
    echo "== 0x$a"
    "$a2l" -f -i -C -e "$elf" "0x$a" | paste - - | sed 's/::h[0-9a-f]\{16\}//'
done

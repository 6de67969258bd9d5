/* Shared parts of the C harness (tests/ffi): the scene's devices over the
 * linked-in bytes, the outcome digest, and the checks. */
#ifndef VTSM_HARNESS_H
#define VTSM_HARNESS_H
#include <stddef.h>
#include <stdint.h>
#include "vtsm.h"

extern const uint8_t scene_map[], scene_map_end[];
extern const uint8_t scene_left[], scene_right[], scene_right_end[];

/* The camera's frame memory and the downlink, behind the callbacks. */
typedef struct Devices {
    const uint8_t *left, *right;
    uint32_t width, height;
    uint32_t windows, telemetry_frames, telemetry_bytes, latches;
    uint64_t window_ticks; /* platform ticks spent inside read_window */
    int fail_windows; /* a fault injected into every window read */
    const uint8_t *map; size_t map_len; /* served by read_map */
} Devices;

int32_t dev_read_window(void *ctx, uint8_t eye, int32_t x, int32_t y, uint32_t w, uint32_t h,
                        uint8_t *out, size_t out_len);
int32_t dev_latch(void *ctx);
int32_t dev_read_map(void *ctx, uint32_t offset, uint8_t *buf, size_t len);
int32_t dev_write_telemetry(void *ctx, uint8_t kind, const uint8_t *payload, size_t len);
uint64_t dev_now(void *ctx);

/* The scene's config with `dev` as the callbacks' context. */
VtsmConfig scene_config(Devices *dev);
Devices scene_devices(void);

/* FNV-1a over the outcome, folded as the Rust firmware folds it
 * (tests/firmware/src/workload.rs, fold_outcome). */
uint64_t outcome_digest(const VtsmOutcome *o);

/* The bad-input checks; returns the number of failed checks. */
int bad_input_tests(uint8_t *storage, size_t storage_len);
/* The C++ wrapper's checks (cpp_wrapper.cpp); the digest of its run. */
int cpp_wrapper_run(uint8_t *storage, size_t storage_len, uint64_t *digest);

/* The platform's clock (instructions under QEMU -icount on the M7, 0 on the host). */
uint64_t platform_ticks(void);
/* Instructions per tick of platform_ticks (0: not counted). */
uint64_t platform_instructions_per_tick(void);

/* RAM for a copy of the map product (the bad-input checks corrupt it). */
extern uint8_t map_copy[];
extern const size_t map_copy_len;
#endif

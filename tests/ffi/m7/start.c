/* Start-up of the C harness on MPS2 AN500 (Cortex-M7): vector table, FPU
 * on, .bss zeroed, newlib's semihosting stdio, SysTick as the clock.
 *
 * Instruction counting as the Rust firmware does it (tests/firmware/src/
 * start/arm.rs): under `qemu-system-arm -icount shift=0` virtual time
 * advances 1 ns per instruction, and SysTick runs from the board's 25 MHz
 * clock, so one tick is 40 instructions; a calibration loop measures it. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

extern int main(void);
extern void initialise_monitor_handles(void);
extern uint8_t __bss_start__[], __bss_end__[], __stack_top[];

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SCB_ICSR (*(volatile uint32_t *)0xE000ED04u)
#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define RELOAD 0x00FFFFFFu

static volatile uint32_t wraps;

void SysTick_Handler(void) { wraps++; }

/* Ticks since SysTick was started (wraps counted by the exception; a
 * pending wrap is counted here). */
uint64_t platform_ticks(void) {
    __asm volatile("cpsid i" ::: "memory");
    uint32_t w = wraps, cur = SYST_CVR;
    if (SCB_ICSR & (1u << 26)) { /* PENDSTSET */
        w++;
        cur = SYST_CVR;
    }
    __asm volatile("cpsie i" ::: "memory");
    return (uint64_t)w * (RELOAD + 1u) + (RELOAD - cur);
}

/* Exactly 2 * n instructions. */
__attribute__((noinline)) void calibration_loop(uint32_t n) {
    __asm volatile("1: subs %0, %0, #1\n bne 1b" : "+r"(n) :: "cc");
}

uint64_t platform_instructions_per_tick(void) {
    const uint32_t loops = 100000u;
    uint64_t t0 = platform_ticks();
    calibration_loop(loops);
    uint64_t ticks = platform_ticks() - t0;
    return ticks ? (2u * (uint64_t)loops + ticks / 2u) / ticks : 0u;
}

/* Called by the library only if a panic path were taken (the image links
 * with the panic-check build, which has none). */
void vtsm_panic(void) { abort(); }

/* newlib's init/fini hooks (no crti/crtn with -nostartfiles; nothing to run). */
void _init(void) {}
void _fini(void) {}

void Default_Handler(void) {
    for (;;) {
    }
}

void Reset_Handler(void) {
    SCB_CPACR |= 0xFu << 20; /* CP10, CP11: full access to the FPU */
    __asm volatile("dsb\n isb" ::: "memory");
    memset(__bss_start__, 0, (size_t)(__bss_end__ - __bss_start__));
    SYST_RVR = RELOAD;
    SYST_CVR = 0;
    SYST_CSR = 7u; /* core clock, interrupt on wrap, enabled */
    initialise_monitor_handles();
    exit(main());
}

__attribute__((section(".isr_vector"), used)) void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)__stack_top,
    Reset_Handler,
    Default_Handler, Default_Handler, Default_Handler, Default_Handler, Default_Handler,
    0, 0, 0, 0,
    Default_Handler, Default_Handler, 0,
    Default_Handler,
    SysTick_Handler,
};

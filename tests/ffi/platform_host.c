/* Host platform of the harness: no cycle counter is read (the digest does
 * not depend on the clock). */
#include "harness.h"
uint64_t platform_ticks(void) { return 0; }
uint64_t platform_instructions_per_tick(void) { return 0; }

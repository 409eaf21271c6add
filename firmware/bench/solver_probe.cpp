// The solver with a bare main and nothing else (no Arduino core): built for -mmcu=avrxmega3
// (the ATmega4809's instruction set) and for the ATmega328P to tell what the solver and the
// float routines it pulls in cost in flash and RAM. The avrxmega3 image has no start-up code
// (Debian's avr-libc lacks the 4809), so it is for sizes only, never for running.
#include <stdint.h>

#include "delta6_solver.h"
#include "generated/delta6_design.h"

// volatile: the compiler may not assume the inputs or drop the outputs.
volatile int16_t g_delta[6];
volatile float g_wrench[6];
volatile uint8_t g_status;

int main() {
    int16_t delta[6];
    float wrench[6];
    for (uint8_t i = 0; i < 6; ++i) delta[i] = g_delta[i];
    g_status = delta6::solve_counts(delta6::design::kSolverConstants, delta, wrench);
    for (uint8_t i = 0; i < 6; ++i) g_wrench[i] = wrench[i];
    for (;;) {
    }
}

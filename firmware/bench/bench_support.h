// What the AVR benchmark sketches share (solver_bench.cpp, residual_bench.cpp): the cycle
// markers the emulator stamps, the stack high-water mark, the frames' header, and the 16-bit
// xorshift whose stream the host regenerates. Each sketch is one translation unit, so the
// definitions below are its own.
#pragma once

#include <Arduino.h>

extern char __bss_end;  // end of static RAM (avr-libc linker scripts)

namespace bench {
namespace {

constexpr uint8_t kStackPaint = 0xA5;

// The memory clobbers keep the compiler from moving the measured code's loads and stores (and
// so its work, which sits between them) across a marker.
inline void mark(uint8_t value) {
    asm volatile("" ::: "memory");
#ifdef GPIOR0
    GPIOR0 = value;
#else
    (void)value;
#endif
    asm volatile("" ::: "memory");
}

// Fill the free RAM between static data and the current stack with a pattern; the lowest
// overwritten byte afterwards gives the deepest stack use.
void paint_stack() {
    char* p = &__bss_end;
    char* limit = reinterpret_cast<char*>(SP) - 16;  // stay clear of this function's frame
    while (p < limit) *p++ = static_cast<char>(kStackPaint);
}

uint16_t peak_stack_bytes() {
    const char* p = &__bss_end;
    while (p < reinterpret_cast<const char*>(RAMEND) && *p == static_cast<char>(kStackPaint)) ++p;
    return static_cast<uint16_t>(RAMEND - reinterpret_cast<uint16_t>(p) + 1);
}

uint16_t xorshift_state = 0xACE1u;

// The same stream on every run (and in the host's copy of it).
uint16_t next_random() {
    xorshift_state ^= static_cast<uint16_t>(xorshift_state << 7);
    xorshift_state ^= static_cast<uint16_t>(xorshift_state >> 9);
    xorshift_state ^= static_cast<uint16_t>(xorshift_state << 8);
    return xorshift_state;
}

void send(const void* data, size_t size) {
    Serial.write(static_cast<const uint8_t*>(data), size);
}

// Every frame starts with 0xD6 and its type byte.
void send_header(char type) {
    const uint8_t head[2] = {0xD6, static_cast<uint8_t>(type)};
    send(head, sizeof head);
}

}  // namespace
}  // namespace bench

// Board layer for the ATmega328P at 16 MHz: the classic Nano, and the image the virtual board
// runs in simavr. Pin map in board_contract.h (docs/firmware.md has the wiring table).
#if defined(__AVR_ATmega328P__)

#include <Arduino.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>   // set_sleep_mode
#include <avr/wdt.h>

#include "app.h"
#include "board.h"
#include "board_contract.h"
#include "encoder_bus.h"
#include "uart_queue.h"

static_assert(F_CPU == 16000000UL, "the UART and timer settings assume 16 MHz");

namespace {

const uint8_t kDataMask = 0x3F << D6_328P_DATA_SHIFT;   // PC0..PC5
const uint8_t kCsMask = 0x3F << D6_328P_CS_SHIFT;       // PD2..PD7
const uint8_t kClk = _BV(D6_328P_CLK_BIT);               // PB0

struct Pins {
  static void selectAll() { PORTD &= static_cast<uint8_t>(~kCsMask); }
  static void deselectAll() { PORTD |= kCsMask; }
  static void clockHigh() { PORTB |= kClk; }
  static void clockLow() { PORTB &= static_cast<uint8_t>(~kClk); }
  static void driveData(uint8_t bits) {
    PORTC = bits;
    DDRC = kDataMask;
  }
  static void writeData(uint8_t bits) { PORTC = bits; }
  static void releaseData() {
    PORTC = kDataMask;   // high first (the last command bit is 1 anyway), then pull-ups
    DDRC = 0;
  }
  static uint8_t readData() { return PINC; }
};
static_assert(D6_328P_DATA_SHIFT == 0, "Pins::readData returns encoder j in bit j");

uint8_t saved_reset_flags __attribute__((section(".noinit")));

}  // namespace

// Runs before the C runtime's initialisation: keep MCUSR (the reset cause) and stop a watchdog
// that a watchdog reset leaves running at its shortest timeout.
extern "C" void delta6_capture_reset_cause() __attribute__((naked, used, section(".init3")));
extern "C" void delta6_capture_reset_cause() {
  saved_reset_flags = MCUSR;
  MCUSR = 0;
  wdt_disable();
}

// The transmit interrupt runs once per byte sent (about 37 a record): in assembly it saves
// only the three registers it uses, about 15 cycles a byte less than the compiler's version.
// It does what uartq::txTake and the clear of UDRIE would: the next byte to UDR0 if the ring
// holds one, otherwise no more interrupts until the main loop queues bytes.
ISR(USART_UDRE_vect, ISR_NAKED) {
  asm volatile(
      "push r24\n\t"
      "in r24, __SREG__\n\t"
      "push r24\n\t"
      "push r30\n\t"
      "push r31\n\t"
      "lds r30, %[tail]\n\t"
      "lds r24, %[head]\n\t"
      "cp r30, r24\n\t"
      "breq 1f\n\t"
      "ldi r31, 0\n\t"
      "subi r30, lo8(-(%[buf]))\n\t"
      "sbci r31, hi8(-(%[buf]))\n\t"
      "ld r24, Z\n\t"
      "sts %[udr], r24\n\t"
      "lds r24, %[tail]\n\t"
      "inc r24\n\t"
      "sts %[tail], r24\n\t"
      "rjmp 2f\n"
      "1:\n\t"
      "lds r24, %[ucsrb]\n\t"
      "andi r24, %[no_udrie]\n\t"
      "sts %[ucsrb], r24\n"
      "2:\n\t"
      "pop r31\n\t"
      "pop r30\n\t"
      "pop r24\n\t"
      "out __SREG__, r24\n\t"
      "pop r24\n\t"
      "reti\n\t"
      :
      : [tail] "i"(&uartq::tx_tail), [head] "i"(&uartq::tx_head), [buf] "i"(uartq::tx_buffer),
        [udr] "n"(_SFR_MEM_ADDR(UDR0)), [ucsrb] "n"(_SFR_MEM_ADDR(UCSR0B)),
        [no_udrie] "n"(0xFF & ~_BV(UDRIE0)));
}
static_assert(uartq::kTxSize == 256, "the transmit interrupt's index wraps at 256");

ISR(USART_RX_vect) { uartq::rxPut(UDR0); }

// A read-modify-write of UCSR0B that the transmit interrupt may interleave with: it can only
// clear UDRIE after the ring ran empty, and setting it again then costs one empty interrupt.
void uartq::enableTxInterrupt() { UCSR0B |= _BV(UDRIE0); }

// Nestable: the UART interrupts must preempt the encoder scan (about 0.2 ms), or received
// bytes would overrun the 2-byte receive buffer at 500000 baud.
ISR(TIMER1_COMPA_vect, ISR_NOBLOCK) { app::onSampleTick(); }

namespace board {

void init() {
  DDRB |= kClk;
  PORTB &= static_cast<uint8_t>(~kClk);
  PORTD |= kCsMask;
  DDRD |= kCsMask;
  DDRC = 0;
  PORTC = kDataMask;   // pull-ups: a sensor that does not answer reads as all ones
#if defined(DELTA6_TEST_HOOKS)
  DDRB &= static_cast<uint8_t>(~_BV(D6_328P_TEST_BIT));
  PORTB |= _BV(D6_328P_TEST_BIT);
#endif
  // 500000 baud: UBRR = 16 MHz / (16 x 500000) - 1 = 1, exact.
  UCSR0A = 0;
  UBRR0 = 1;
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);   // 8N1
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  set_sleep_mode(SLEEP_MODE_IDLE);
}

uint8_t resetCause() {
  const uint8_t f = saved_reset_flags;
  uint8_t out = 0;
  if (f & _BV(PORF)) out |= 0x01;
  if (f & _BV(BORF)) out |= 0x02;
  if (f & _BV(EXTRF)) out |= 0x04;
  if (f & _BV(WDRF)) out |= 0x08;
  return out;
}

uint32_t serialNumber() { return 0; }

void startSampling(uint16_t rate_hz) {
  // Timer 1 in CTC mode: the smallest prescaler whose 16-bit count holds one period. The
  // period is rounded to the timer's tick (0.5 us up to 2 ms periods); micros() is the truth.
  // In flash: constant tables would take RAM otherwise.
  static const uint16_t kPrescale[] PROGMEM = {8, 64, 256, 1024};
  static const uint8_t kSelect[] PROGMEM = {_BV(CS11), _BV(CS11) | _BV(CS10), _BV(CS12),
                                            _BV(CS12) | _BV(CS10)};
  uint8_t k = 0;
  uint32_t ticks = 0;
  for (; k < 4; ++k) {
    ticks = (F_CPU / pgm_read_word(&kPrescale[k]) + rate_hz / 2) / rate_hz;
    if (ticks <= 65536UL) break;
  }
  if (k == 4) {
    k = 3;
    ticks = 65536UL;
  }
  const uint8_t sreg = SREG;
  cli();
  TCCR1B = 0;
  TCCR1A = 0;
  TCNT1 = 0;
  OCR1A = static_cast<uint16_t>(ticks - 1);
  TIFR1 = _BV(OCF1A);
  TIMSK1 = _BV(OCIE1A);
  TCCR1B = _BV(WGM12) | pgm_read_byte(&kSelect[k]);
  SREG = sreg;
}

void scanEncoders(uint16_t word[6], uint16_t inverse[6]) { bus::scan<Pins>(word, inverse); }

void watchdogStart(uint16_t rate_hz) { wdt_enable(rate_hz >= 10 ? WDTO_250MS : WDTO_2S); }

void watchdogKick() { wdt_reset(); }

#if defined(DELTA6_TEST_HOOKS)
bool testHangRequested() { return !(PINB & _BV(D6_328P_TEST_BIT)); }
#endif

}  // namespace board

#endif  // __AVR_ATmega328P__

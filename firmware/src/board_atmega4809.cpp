// Board layer for the ATmega4809 of the Arduino Nano Every (PlatformIO env nano_every).
//
// NOT built or run in CI: Debian's avr-libc has no ATmega4809 support, so this file is only
// compiled by PlatformIO on users' machines. It mirrors board_atmega328p.cpp (which the
// virtual board runs) with the 4809's peripherals; docs/firmware.md lists what is unverified.
//
// Pin map (Nano Every pin names; the 4809 has no port with six free header pins for the chip
// selects, so they take two ports, written one instruction apart):
//   clock        PA0  D2
//   chip select  PE0..PE3 = D11, D12, D13, D8 (encoders 1-4); PB0, PB1 = D9, D10 (5-6)
//   data         PD0..PD5 = A3, A2, A1, A0, A6, A7 (encoders 1-6)
//   USB serial   USART3 on PB4/PB5 (to the SAMD11 bridge; not on the headers)
#if defined(__AVR_ATmega4809__)

#include <Arduino.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>   // set_sleep_mode

#include "app.h"
#include "board.h"
#include "board_contract.h"
#include "encoder_bus.h"
#include "uart_queue.h"

namespace {

const uint8_t kClk = PIN0_bm;                  // PA0
const uint8_t kCsE = 0x0F;                     // PE0..PE3
const uint8_t kCsB = PIN0_bm | PIN1_bm;        // PB0, PB1
const uint8_t kData = 0x3F;                    // PD0..PD5

struct Pins {
  static void selectAll() {
    VPORTE.OUT &= static_cast<uint8_t>(~kCsE);
    VPORTB.OUT &= static_cast<uint8_t>(~kCsB);
  }
  static void deselectAll() {
    VPORTE.OUT |= kCsE;
    VPORTB.OUT |= kCsB;
  }
  static void clockHigh() { VPORTA.OUT |= kClk; }
  static void clockLow() { VPORTA.OUT &= static_cast<uint8_t>(~kClk); }
  static void driveData(uint8_t bits) {
    VPORTD.OUT = bits;
    VPORTD.DIR = kData;
  }
  static void writeData(uint8_t bits) { VPORTD.OUT = bits; }
  static void releaseData() { VPORTD.DIR = 0; }   // pull-ups stay on (PINnCTRL)
  static uint8_t readData() { return VPORTD.IN; }
};

uint8_t sample_postscale = 1;   // timer periods per sample (below ~4 Hz)
volatile uint8_t sample_countdown = 1;

uint8_t saved_reset_flags __attribute__((section(".noinit")));

void waitWatchdogSync() {
  while (WDT.STATUS & WDT_SYNCBUSY_bm) {
  }
}

}  // namespace

// Before the C runtime's initialisation: keep the reset flags, then clear them.
extern "C" void delta6_capture_reset_cause() __attribute__((naked, used, section(".init3")));
extern "C" void delta6_capture_reset_cause() {
  saved_reset_flags = RSTCTRL.RSTFR;
  RSTCTRL.RSTFR = saved_reset_flags;   // write one to clear
}

ISR(USART3_DRE_vect) {
  uint8_t b;
  if (uartq::txTake(&b)) {
    USART3.TXDATAL = b;
  } else {
    USART3.CTRLA &= static_cast<uint8_t>(~USART_DREIE_bm);
  }
}

ISR(USART3_RXC_vect) { uartq::rxPut(USART3.RXDATAL); }

void uartq::enableTxInterrupt() { USART3.CTRLA |= USART_DREIE_bm; }

// Level 0; the receive interrupt is level 1 (board::init) and preempts the encoder scan.
ISR(TCB0_INT_vect) {
  TCB0.INTFLAGS = TCB_CAPT_bm;
  if (--sample_countdown) return;
  sample_countdown = sample_postscale;
  app::onSampleTick();
}

namespace board {

void init() {
  VPORTA.OUT &= static_cast<uint8_t>(~kClk);
  VPORTA.DIR |= kClk;
  VPORTE.OUT |= kCsE;
  VPORTE.DIR |= kCsE;
  VPORTB.OUT |= kCsB;
  VPORTB.DIR |= kCsB;
  VPORTD.DIR = 0;
  PORTD_PIN0CTRL = PORT_PULLUPEN_bm;   // a sensor that does not answer reads as all ones
  PORTD_PIN1CTRL = PORT_PULLUPEN_bm;
  PORTD_PIN2CTRL = PORT_PULLUPEN_bm;
  PORTD_PIN3CTRL = PORT_PULLUPEN_bm;
  PORTD_PIN4CTRL = PORT_PULLUPEN_bm;
  PORTD_PIN5CTRL = PORT_PULLUPEN_bm;

  // USART3 on its alternate pins PB4 (TX) / PB5 (RX): the Nano Every's USB bridge.
  PORTMUX.USARTROUTEA = static_cast<uint8_t>((PORTMUX.USARTROUTEA & ~PORTMUX_USART3_gm) |
                                             PORTMUX_USART3_ALT1_gc);
  VPORTB.OUT |= PIN4_bm;
  VPORTB.DIR |= PIN4_bm;
  // BAUD = 64 f / (16 baud): 128 at 16 MHz, exact.
  USART3.BAUD = static_cast<uint16_t>((64UL * F_CPU + 8UL * kBaud) / (16UL * kBaud));
  USART3.CTRLC = USART_CHSIZE_8BIT_gc;   // asynchronous 8N1
  USART3.CTRLA = USART_RXCIE_bm;
  USART3.CTRLB = USART_RXEN_bm | USART_TXEN_bm;
  CPUINT.LVL1VEC = USART3_RXC_vect_num;

  set_sleep_mode(SLEEP_MODE_IDLE);
}

uint8_t resetCause() { return saved_reset_flags; }   // the common encoding is RSTFR's

uint32_t serialNumber() {
  // FNV-1a over the ten factory serial-number bytes.
  const volatile uint8_t* sernum = &SIGROW.SERNUM0;
  uint32_t h = 2166136261UL;
  for (uint8_t i = 0; i < 10; ++i) {
    h ^= sernum[i];
    h *= 16777619UL;
  }
  return h;
}

void startSampling(uint16_t rate_hz) {
  // TCB0 counts the clock of TCA0, which the Arduino core runs at F_CPU / 64 (250 kHz at
  // 16 MHz): 4 us ticks. Below ~4 Hz a period needs more than 16 bits: count several.
  uint32_t ticks = (F_CPU / 64UL + rate_hz / 2) / rate_hz;
  uint8_t postscale = 1;
  while (ticks > 65536UL) {
    ++postscale;
    ticks = (F_CPU / 64UL + rate_hz * postscale / 2) / (static_cast<uint32_t>(rate_hz) * postscale);
  }
  const uint8_t sreg = SREG;
  cli();
  TCB0.CTRLA = 0;
  TCB0.CTRLB = TCB_CNTMODE_INT_gc;
  TCB0.CCMP = static_cast<uint16_t>(ticks - 1);
  TCB0.CNT = 0;
  TCB0.INTFLAGS = TCB_CAPT_bm;
  TCB0.INTCTRL = TCB_CAPT_bm;
  sample_postscale = postscale;
  sample_countdown = postscale;
  TCB0.CTRLA = TCB_CLKSEL_CLKTCA_gc | TCB_ENABLE_bm;
  SREG = sreg;
}

void scanEncoders(uint16_t word[6], uint16_t inverse[6]) { bus::scan<Pins>(word, inverse); }

void watchdogStart(uint16_t rate_hz) {
  // avr-libc's WDTO_* values are the classic AVRs'; the 4809 has its own period codes.
  waitWatchdogSync();
  _PROTECTED_WRITE(WDT.CTRLA, rate_hz >= 10 ? WDT_PERIOD_256CLK_gc : WDT_PERIOD_2KCLK_gc);
}

void watchdogKick() { __builtin_avr_wdr(); }

}  // namespace board

#endif  // __AVR_ATmega4809__

// The parts of the board layer that both AVRs share: the UART rings' main-loop side, the
// queued-record marker, sleeping, the EEPROM (avr-libc) and the clock (the Arduino core). The register work is in board_atmega4809.cpp and
// board_atmega328p.cpp.
#if defined(__AVR_ATmega328P__) || defined(__AVR_ATmega4809__)

#include <Arduino.h>
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "board.h"
#include "board_contract.h"
#include "delta6_device.h"
#include "uart_queue.h"

static_assert(board::kTxQueue == uartq::kTxSize, "one transmit queue size");
static_assert(board::kTxQueue - 1 >= delta6::Device::kMinTxBuffer,
              "the transmit queue holds the largest record");
// The longest command frame: its payload (at most the command buffer), the CRC, COBS's code
// byte and the delimiter.
static_assert(uartq::kRxSize >= delta6::proto::kCommandBuffer + delta6::proto::kFrameOverhead,
              "the receive ring holds the longest command frame");
static_assert((uartq::kRxSize & (uartq::kRxSize - 1)) == 0, "the receive ring's size is a power of two");

namespace uartq {

uint8_t tx_buffer[kTxSize];
volatile uint8_t tx_head = 0;
volatile uint8_t tx_tail = 0;
uint8_t rx_buffer[kRxSize];
volatile uint8_t rx_head = 0;
volatile uint8_t rx_tail = 0;

}  // namespace uartq

namespace board {

// .noinit: neither avr-libc's start-up code nor the Arduino core touches it.
static uint16_t boot_counter __attribute__((section(".noinit")));

uint16_t bootId() {
  boot_counter = static_cast<uint16_t>(boot_counter + 1);
  return boot_counter;
}

uint16_t txSpace() { return static_cast<uint16_t>(kTxQueue - 1 - uartq::txQueued()); }

void markRecordQueued() {
  const uint8_t sreg = SREG;
  cli();
  mark(D6_MARK_RECORD_QUEUED, uartq::txQueued());
  SREG = sreg;
}

void txWrite(const uint8_t* data, uint16_t n) {
  uint8_t head = uartq::tx_head;
  for (uint16_t i = 0; i < n; ++i) uartq::tx_buffer[head++] = data[i];
  uartq::tx_head = head;
  uartq::enableTxInterrupt();
}

bool rxAvailable() { return uartq::rx_head != uartq::rx_tail; }

int16_t rxRead() {
  const uint8_t tail = uartq::rx_tail;
  if (tail == uartq::rx_head) return -1;
  const uint8_t b = uartq::rx_buffer[tail];
  uartq::rx_tail = static_cast<uint8_t>((tail + 1) & (uartq::kRxSize - 1));
  return b;
}

uint32_t micros() { return ::micros(); }

void eepromRead(uint16_t address, uint8_t* data, uint16_t n) {
  eeprom_read_block(data, reinterpret_cast<const void*>(address), n);
}

void eepromWrite(uint16_t address, const uint8_t* data, uint16_t n) {
  for (uint16_t i = 0; i < n; ++i) {
    watchdogKick();   // a byte takes about 3.4 ms; a whole blob longer than the timeout
    eeprom_update_byte(reinterpret_cast<uint8_t*>(address + i), data[i]);
  }
  eeprom_busy_wait();
}

void idle(bool (*pending)()) {
  cli();
  if (pending()) {
    sei();
    return;
  }
  mark(D6_MARK_IDLE);
  sleep_enable();
  sei();
  sleep_cpu();   // sei's next instruction runs first: no interrupt slips in between
  sleep_disable();
  mark(D6_MARK_WAKE);
}

}  // namespace board

#endif

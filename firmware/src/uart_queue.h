// The interrupt-driven UART's two rings, shared by the AVR board layers: the main loop queues
// records (board::txWrite) and takes received bytes (board::rxRead); the board's interrupt
// handlers call txTake and rxPut. Single producer, single consumer, 8-bit indices: no locks.
#ifndef DELTA6_UART_QUEUE_H
#define DELTA6_UART_QUEUE_H

#include <stdint.h>

namespace uartq {

const uint16_t kTxSize = 256;   // the indices wrap by themselves
// A power of two. The 328P (2 KB of RAM; the emulator's stand-in for the Nano Every) keeps 64:
// with a calibrated solver its static data and peak stack would not fit 2 KB with 128. 64
// bytes still hold the longest command frame with room for the start of the next; a host
// sends one command and waits for its answer (bytes beyond a full ring are dropped, the
// command's CRC fails and it is retried).
#if defined(__AVR_ATmega328P__)
const uint8_t kRxSize = 64;
#else
const uint8_t kRxSize = 128;
#endif

extern uint8_t tx_buffer[kTxSize];
extern volatile uint8_t tx_head;   // written by the main loop
extern volatile uint8_t tx_tail;   // written by the interrupt
extern uint8_t rx_buffer[kRxSize];
extern volatile uint8_t rx_head;   // written by the interrupt
extern volatile uint8_t rx_tail;   // written by the main loop

// Transmit interrupt: the next byte to send, if any.
inline bool txTake(uint8_t* b) {
  const uint8_t tail = tx_tail;
  if (tail == tx_head) return false;
  *b = tx_buffer[tail];
  tx_tail = static_cast<uint8_t>(tail + 1);
  return true;
}

// Receive interrupt: a full ring drops the byte (the command's CRC then fails; it is retried).
inline void rxPut(uint8_t b) {
  const uint8_t head = rx_head;
  const uint8_t next = static_cast<uint8_t>((head + 1) & (kRxSize - 1));
  if (next != rx_tail) {
    rx_buffer[head] = b;
    rx_head = next;
  }
}

inline uint8_t txQueued() { return static_cast<uint8_t>(tx_head - tx_tail); }

// Provided by the board file: let the transmit interrupt run.
void enableTxInterrupt();

}  // namespace uartq

#endif  // DELTA6_UART_QUEUE_H

// Host-only stand-in for the board layer: a transmit queue drained at the baud rate, an
// EEPROM array and a settable clock. Used by the simulated device (delta6_sim.cpp, loaded by
// the host library through ctypes) and by the sanitizer fuzz driver. Not firmware code: it may
// use the standard library.
#ifndef DELTA6_SIM_HARDWARE_H
#define DELTA6_SIM_HARDWARE_H

#include <stdint.h>
#include <string.h>

#include <vector>

#include "delta6_device.h"

namespace delta6 {
namespace sim {

const uint16_t kEepromSize = 256;

class SimHardware : public Hardware {
 public:
  SimHardware(uint32_t baud, uint16_t tx_capacity)
      : baud_(baud), capacity_(tx_capacity), level_(0.0), drained_at_us_(0), now_us_(0),
        rate_hz_(0), rate_changes_(0), eeprom_writes_(0), eeprom_broken_(false), head_(0) {
    memset(eeprom_, 0xFF, sizeof(eeprom_));  // an erased EEPROM reads 0xFF
  }

  // The clock; the device's UART queue drains at baud / 10 bytes per second meanwhile.
  void setTime(uint32_t us) {
    if (baud_ != 0) {
      const double elapsed = static_cast<double>(static_cast<uint32_t>(us - drained_at_us_));
      level_ -= elapsed * baud_ / 10.0 / 1e6;
      if (level_ < 0.0) level_ = 0.0;
    } else {
      level_ = 0.0;
    }
    drained_at_us_ = us;
    now_us_ = us;
  }

  uint16_t txSpace() override {
    const double space = capacity_ - level_;
    return space <= 0.0 ? 0 : static_cast<uint16_t>(space);
  }
  void txWrite(const uint8_t* data, uint16_t n) override {
    level_ += n;
    out_.insert(out_.end(), data, data + n);
  }
  void eepromRead(uint16_t address, uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) data[i] = eeprom_[(address + i) % kEepromSize];
  }
  void eepromWrite(uint16_t address, const uint8_t* data, uint16_t n) override {
    ++eeprom_writes_;
    if (eeprom_broken_) return;  // a dead EEPROM: writes do nothing
    for (uint16_t i = 0; i < n; ++i) eeprom_[(address + i) % kEepromSize] = data[i];
  }
  uint32_t micros() override { return now_us_; }
  void sampleRateChanged(uint16_t rate_hz) override {
    rate_hz_ = rate_hz;
    ++rate_changes_;
  }

  // Host side of the link.
  uint32_t pending() const { return static_cast<uint32_t>(out_.size() - head_); }
  uint32_t read(uint8_t* dst, uint32_t cap) {
    uint32_t n = pending();
    if (n > cap) n = cap;
    if (n) memcpy(dst, out_.data() + head_, n);
    head_ += n;
    if (head_ == out_.size()) {
      out_.clear();
      head_ = 0;
    }
    return n;
  }

  uint8_t* eeprom() { return eeprom_; }
  uint16_t rate() const { return rate_hz_; }
  uint32_t rateChanges() const { return rate_changes_; }
  uint32_t eepromWrites() const { return eeprom_writes_; }
  void breakEeprom(bool broken) { eeprom_broken_ = broken; }

 private:
  uint32_t baud_;
  uint16_t capacity_;
  double level_;
  uint32_t drained_at_us_;
  uint32_t now_us_;
  uint16_t rate_hz_;
  uint32_t rate_changes_;
  uint32_t eeprom_writes_;
  bool eeprom_broken_;
  uint8_t eeprom_[kEepromSize];
  std::vector<uint8_t> out_;
  size_t head_;
};

}  // namespace sim
}  // namespace delta6

#endif

// The Delta6 firmware: Arduino sketch glue. All the work is in app.cpp (the loop), the board
// files (hardware) and lib/delta6_core (solver and protocol).
#include <Arduino.h>

#include "app.h"

void setup() { app::setup(); }

void loop() { app::loop(); }

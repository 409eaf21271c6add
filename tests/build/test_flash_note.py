"""The ATmega328P image's flash is judged against a classic Nano's bootloader budget, and an
image over it is told what it still fits."""
import re

import pytest

from delta6.build import avrbuild


def test_within_the_classic_budget_says_nothing():
    assert avrbuild.flash_note(avrbuild.NANO.flash_bytes) == ""


def test_over_the_classic_budget_says_what_it_still_fits():
    note = avrbuild.flash_note(avrbuild.NANO.flash_bytes + 1)
    assert "over a classic Nano's 30,720 B" in note and "within the 32 KB" in note
    assert "over the 32 KB" in avrbuild.flash_note(32_769)


@pytest.mark.avr
def test_an_image_that_does_not_fit_is_one_line(tmp_path):
    """The linker's multi-line dump ("region `text' overflowed by N bytes") becomes one line:
    which image, how many bytes over, and the likely cause."""
    src = tmp_path / "big.c"
    src.write_text('#include <avr/pgmspace.h>\n'
                   'const char a[16350] PROGMEM = {1};\n'
                   'const char b[16350] PROGMEM = {2};\n'
                   'volatile char d[16] = {1, 2, 3};\n'
                   'int main(void) {\n'
                   '    return pgm_read_byte(&a[7]) + pgm_read_byte(&b[9]) + d[3];\n'
                   '}\n')
    with pytest.raises(avrbuild.BuildError) as info:
        avrbuild.build_image("too-big", [src], arduino=False, out_dir=tmp_path / "out")
    message = str(info.value)
    assert "\n" not in message, message
    assert "too-big does not fit the atmega328p: " in message
    over = int(re.search(r"([\d,]+) bytes over its flash", message)[1].replace(",", ""))
    assert 0 < over < 500     # 32,700 B of tables and the start-up code, less 32,768
    assert "joint box" in message and "calibration" in message


@pytest.mark.avr
def test_an_image_over_its_static_ram_is_not_blamed_on_the_trig_tables(tmp_path):
    src = tmp_path / "fat.c"
    src.write_text('volatile char ram[2100] = {1};\n'
                   'int main(void) { return ram[7]; }\n')
    with pytest.raises(avrbuild.BuildError) as info:
        avrbuild.build_image("too-fat", [src], arduino=False, out_dir=tmp_path / "out")
    message = str(info.value)
    assert "\n" not in message, message
    assert "over its static RAM" in message and "Static RAM holds" in message
    assert "trig tables" not in message

"""The ATmega328P image's flash is judged against a classic Nano's bootloader budget, and an
image over it is told what it still fits."""
from delta6.build import avrbuild


def test_within_the_classic_budget_says_nothing():
    assert avrbuild.flash_note(avrbuild.NANO.flash_bytes) == ""


def test_over_the_classic_budget_says_what_it_still_fits():
    note = avrbuild.flash_note(avrbuild.NANO.flash_bytes + 1)
    assert "over a classic Nano's 30,720 B" in note and "within the 32 KB" in note
    assert "over the 32 KB" in avrbuild.flash_note(32_769)

# Two commands do everything from a fresh clone: `make demo` (the main job) and `make test`.
# Each creates the virtualenv and builds what it needs.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
FMU    := build/plant/quadrotor.fmu
CC     ?= gcc
CFLAGS_BENCH := -std=c11 -O2 -Wall -Wextra -Werror

PLANT_SOURCES := $(wildcard plant/c/*.c plant/c/*.h plant/fmi2/*) plant/variables.py plant/build.py

SHIM   := build/librigshim.so
# the C extension modules (the sensors' sampling chain; the plant's steps): their names carry the
# interpreter's suffix
EXT := $(shell $(PYTHON) -c 'import importlib.machinery as m; print(m.EXTENSION_SUFFIXES[0])')
NATIVE := build/_rignative$(EXT) build/_plantsteps$(EXT) build/_rigpace$(EXT) build/_riglockstep$(EXT) \
	build/_rigtelemetry$(EXT) build/_rigevents$(EXT)
# the modules rig/compiled.py compiles with mypyc (its MODULES, read from there)
COMPILED := build/mypyc/manifest.json
COMPILED_SOURCES := $(shell $(PYTHON) -m rig.compiled --sources)

DUT_BIN := build/dut/fc

# the virtual bridge (docs/design.md §8): the bridge core as a Linux process, linking the one chip core
# (BRIDGE_CHIPS, the lockstep session's; its register tables generated into build/gen). Strict C99, as
# on an MCU; no fused multiply-adds, so its encoding rounds as the session's does
VBRIDGE := build/vbridge
BRIDGE_CHIPS := emulators/chips
BRIDGE_CFLAGS := -std=c99 -pedantic -O2 -Wall -Wextra -Werror -ffp-contract=off -Ibuild/gen -I$(BRIDGE_CHIPS) \
	-Ibridge/core -Irig/shim

.PHONY: all venv fmu shim native chips compiled dut vbridge firmware avr stm32 avr-toolchain test-packages mcu-test-firmware stm32-engine stm32-test-firmware demo test test-slow lint lint-sources bench clean docs-images

all: fmu shim native compiled dut vbridge

venv: $(VENV)/.installed
$(VENV)/.installed: pyproject.toml tools/bootstrap.sh
	PYTHON=$(PYTHON) tools/bootstrap.sh
	touch $@

fmu: $(FMU)
$(FMU): $(PLANT_SOURCES) | venv
	$(PY) -m rig.plant.build

shim: $(SHIM)
# rigshim.c includes the shim's other .c files (one translation unit); keeper.c is the keeper's
$(SHIM): $(wildcard rig/shim/*.c rig/shim/*.h) rig/shim/build.py | venv
	$(PY) -m rig.shim.build

native: $(NATIVE)
# the chip core is compiled into the same library, with its register tables generated from the Python
# ones (emulators/chips/gen.py): any of them changing rebuilds it
CHIP_FILES := $(wildcard emulators/chips/*.c emulators/chips/*.h) emulators/chips/gen.py emulators/registers.py \
	emulators/mpu6050.py emulators/hmc5883l.py emulators/ms5611.py
build/_rignative$(EXT): emulators/c/fastcalls.c emulators/c/sampling.c emulators/c/need_tuple.h $(CHIP_FILES) emulators/native.py plant/native_build.py | venv
	$(PY) -m rig.emulators.native
chips: build/_rignative$(EXT)
# the real-time loop's wait (rig/pace; also built on first use)
build/_rigpace$(EXT): rig/pace/pace.c rig/pace/__init__.py plant/native_build.py | venv
	$(PY) -c 'import rig.pace; rig.pace.native()'
# the DUT's telemetry lines read after a run (rig/telemetry; also built on first use)
build/_rigtelemetry$(EXT): rig/telemetry/lines.c rig/telemetry/__init__.py plant/native_build.py | venv
	$(PY) -c 'import rig.telemetry; rig.telemetry.native()'
# the lockstep fast path (rig/lockstep): the wire's header is the shim's, the chip core's and the need's
# headers the emulators'
build/_riglockstep$(EXT): $(wildcard rig/lockstep/*.c) rig/lockstep/__init__.py rig/shim/protocol.h emulators/chips/chip_core.h \
	emulators/c/need_tuple.h plant/c/plant_steps.c rig/event_queue/queue.h plant/native_build.py | venv
	$(PY) -m rig.lockstep
# the scheduler's event queue (rig/event_queue; also built on first use)
build/_rigevents$(EXT): rig/event_queue/queue.c rig/event_queue/queue.h rig/event_queue/__init__.py plant/native_build.py | venv
	$(PY) -c 'import rig.event_queue; rig.event_queue.build()'
build/_plantsteps$(EXT): plant/c/steps_module.c plant/c/plant_steps.c plant/steps.py plant/native_build.py | venv
	$(PY) -m rig.plant.steps

compiled: $(COMPILED)
$(COMPILED): $(COMPILED_SOURCES) rig/compiled.py rig/mypyc_build.py | venv
	$(PY) -m rig.mypyc_build

dut: $(DUT_BIN)
$(DUT_BIN): $(wildcard dut/src/* dut/linux/* dut/tests/* dut/Makefile) bench/fc_bench.c
	$(MAKE) -s -C dut

vbridge: $(VBRIDGE)
$(VBRIDGE): $(wildcard bridge/core/*.[ch] bridge/posix/*.[ch]) $(CHIP_FILES) rig/shim/protocol.h \
		rig/bridge/messages.py rig/bridge/gen.py | venv
	$(PY) -m rig.bridge.gen >/dev/null
	$(PY) -m rig.emulators.chips.gen >/dev/null
	$(CC) $(BRIDGE_CFLAGS) -o $@ bridge/posix/*.c bridge/core/*.c $(BRIDGE_CHIPS)/*.c -lm

# the bridge firmware for the STM32G431 (docs/bridge-firmware.md): build/firmware/bridge.elf, .bin, .map
# with Debian's arm-none-eabi-gcc; prints flash and RAM used against 128 KB / 32 KB and fails when over
# (rig/bridge/firmware.py rebuilds only when a source is newer)
firmware: venv test-packages
	$(PY) -m rig.bridge.firmware

# the reference FC as ATmega2560 firmware (docs/avr-fc.md): build/avr/fc.elf, .hex, .eep; prints flash, RAM
# and EEPROM use against 256 KB / 8 KB / 4 KB and fails when over
avr: avr-toolchain
	$(MAKE) -s -C dut avr

# the reference FC as STM32F405 firmware (docs/reference-fc.md): build/stm32/fc.elf and .map, with Debian's
# arm-none-eabi-gcc and newlib (tools/test-packages.sh); prints its flash and RAM use
stm32: test-packages
	$(MAKE) -s -C dut stm32

# avr-gcc, avr-libc and libsimavr (tools/avr-toolchain.sh), only when missing: the MCU tier and the AVR
# firmware need them, the demo does not
avr-toolchain:
ifndef INSTALLED
	tools/avr-toolchain.sh
endif

# what make test needs beyond the demo (tools/test-packages.sh): linters, the ARM and AVR toolchains,
# QEMU, i2c-tools, poppler; only what is missing
test-packages: venv
ifndef INSTALLED
	tools/test-packages.sh
endif

# the MCU tier's test firmwares (tests/mcu/firmware, docs/mcu.md), each for both MCUs:
# build/mcu/test/NAME-atmega328p.elf and NAME-atmega2560.elf; the TWI replayer's trace tables are generated
# from emulators/traces/*.json
MCU_FW_DIR := tests/mcu/firmware
MCU_FW_NAMES := $(basename $(notdir $(wildcard $(MCU_FW_DIR)/*.c)))
MCU_FW := $(foreach n,$(MCU_FW_NAMES),build/mcu/test/$(n)-atmega328p.elf build/mcu/test/$(n)-atmega2560.elf)
AVR_CFLAGS := -std=gnu11 -DF_CPU=16000000UL -Os -Wall -Wextra -Werror -I$(MCU_FW_DIR) -Ibuild/mcu/test
mcu-test-firmware: avr-toolchain $(MCU_FW)
build/mcu/test/traces.h: $(wildcard emulators/traces/*.json) tests/mcu/gen_traces.py emulators/trace.py | venv
	$(PY) -m tests.mcu.gen_traces $@
build/mcu/test/twi_replay-atmega328p.elf build/mcu/test/twi_replay-atmega2560.elf: build/mcu/test/traces.h
build/mcu/test/%-atmega328p.elf: $(MCU_FW_DIR)/%.c $(wildcard $(MCU_FW_DIR)/*.h) | avr-toolchain
	@mkdir -p $(@D)
	avr-gcc -mmcu=atmega328p $(AVR_CFLAGS) -o $@ $<
build/mcu/test/%-atmega2560.elf: $(MCU_FW_DIR)/%.c $(wildcard $(MCU_FW_DIR)/*.h) | avr-toolchain
	@mkdir -p $(@D)
	avr-gcc -mmcu=atmega2560 $(AVR_CFLAGS) -o $@ $<

# the STM32 tier's engine (docs/mcu.md): qemu-system-arm built from Debian's QEMU 7.2 source package with
# the models of qemu/ compiled in, cached outside the tree by the SHA-256 of its inputs
# (~/.cache/rig/stm32-engine/KEY/qemu-system-arm; rig/mcu/stm32_engine.py); again with nothing changed,
# it builds nothing and prints where the binary is. Installs its build dependencies when missing
stm32-engine: venv
	$(PY) -m rig.mcu.stm32_engine

# the STM32 tier's test firmwares (tests/stm32/firmware, docs/mcu.md): build/stm32/test/NAME.elf for the
# STM32F405, freestanding (their own start-up; semihosting to report), with Debian's arm-none-eabi-gcc
STM32_FW_DIR := tests/stm32/firmware
STM32_FW_NAMES := $(filter-out startup,$(basename $(notdir $(wildcard $(STM32_FW_DIR)/*.c))))
STM32_FW := $(foreach n,$(STM32_FW_NAMES),build/stm32/test/$(n).elf) build/stm32/test/i2c_poll_pb8.elf
STM32_CFLAGS := -mcpu=cortex-m4 -mthumb -mfloat-abi=soft -std=c11 -O2 -g -Wall -Wextra -Werror -ffreestanding \
	-nostdlib -nostartfiles -T$(STM32_FW_DIR)/stm32f405.ld -Idut/stm32
stm32-test-firmware: test-packages $(STM32_FW)
build/stm32/test/%.elf: $(STM32_FW_DIR)/%.c $(STM32_FW_DIR)/startup.c $(wildcard $(STM32_FW_DIR)/*.h) \
		$(STM32_FW_DIR)/stm32f405.ld dut/stm32/stm32f405.h
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(STM32_CFLAGS) -o $@ $< $(STM32_FW_DIR)/startup.c
# the I2C replayer plays the MCU tier's trace tables (build/mcu/test/traces.h)
build/stm32/test/i2c_replay.elf: build/mcu/test/traces.h
build/stm32/test/i2c_replay.elf: STM32_CFLAGS += -Ibuild/mcu/test
# i2c_poll.c again with I2C1 on PB8/PB9 (the Black Pill's pins)
build/stm32/test/i2c_poll_pb8.elf: $(STM32_FW_DIR)/i2c_poll.c $(STM32_FW_DIR)/startup.c \
		$(wildcard $(STM32_FW_DIR)/*.h) $(STM32_FW_DIR)/stm32f405.ld dut/stm32/stm32f405.h
	@mkdir -p $(@D)
	arm-none-eabi-gcc $(STM32_CFLAGS) -DI2C1_SCL_PIN=8u -o $@ $< $(STM32_FW_DIR)/startup.c

# the builds two at a time, mypyc's first (the longest): 40-50 s of the demo's 2-3 minutes went to it
# while everything else waited
demo: venv
	$(MAKE) -s -j2 INSTALLED=1 $(COMPILED) fmu shim native dut
	$(VENV)/bin/rig run --out build/reports --pdf

# docs/acceptance-report-page.png: page 3 (the first scenario's section) of a two-scenario acceptance PDF;
# docs/service-run-page.png: rig serve's page of a run
docs-images: venv fmu shim native compiled dut
	rm -rf build/docs-report
	$(VENV)/bin/rig run rc_loss_failsafe fault_gyro_stuck --out build/docs-report --pdf --operator "A. Tester"
	pdftoppm -f 3 -l 3 -r 80 -png -singlefile build/docs-report/acceptance.pdf docs/acceptance-report-page
	$(PY) tools/service_screenshot.py
	$(PY) tools/mcap_screenshot.py build/docs-report/fault_gyro_stuck/run.mcap

# our C, in one style (.clang-format); the FMI headers are vendored as they came
C_SOURCES := $(filter-out plant/fmi2/%,$(wildcard dut/src/*.[ch] dut/linux/*.[ch] dut/avr/*.[ch] dut/stm32/*.[ch] dut/tests/*.c emulators/c/*.[ch] rig/lockstep/*.c rig/telemetry/*.c rig/pace/*.c emulators/chips/*.[ch] plant/c/*.[ch] \
	rig/shim/*.[ch] bridge/*/*.[ch] bench/*.c tests/rig/device_clients/*.c rig/mcu/*.[ch] tests/mcu/firmware/*.c \
	tests/stm32/firmware/*.[ch] qemu/hw/*.[ch]))

lint: venv test-packages
	$(MAKE) -s lint-sources

# the checks alone, with what they need installed: make test runs them beside the builds, two jobs at a
# time (mypyc's analysis keeps its mypy cache in the build's temporary folder, rig/mypyc_build.py, so
# mypy's SQLite cache in .mypy_cache is this job's alone)
lint-sources:
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy
	clang-format --dry-run --Werror $(C_SOURCES)

# make test installs what is missing, then builds what the suite runs against (the STM32 engine too:
# from its cache in a second when its inputs are unchanged, ~3 minutes of two cores when they are not)
# and checks the sources two jobs at a time (INSTALLED=1: that make installs nothing again; the builds write their generated
# headers and libraries atomically, so two of them may make the same one at once), then runs the suite
# on every core (pytest-xdist; each worker holds a core: tests/conftest.py), then the tests paced by the
# wall clock alone (marker paced: tests/realtime.py), which ends with the count of those that verified
# nothing and fails above half of them (tests/suite_rules.py, tests/README.md). TEST_JOBS=1: one process.
TEST_JOBS ?= $(shell nproc 2>/dev/null || echo 2)
TEST_BUILDS := stm32-engine mcu-test-firmware $(STM32_FW) avr stm32 $(FMU) $(SHIM) $(NATIVE) $(DUT_BIN) $(VBRIDGE) firmware
test: venv test-packages
	$(MAKE) -s -j2 INSTALLED=1 $(COMPILED) lint-sources $(TEST_BUILDS)
	$(PY) -m pytest -q -m "not slow and not paced" -n $(TEST_JOBS) --built --durations=25
	$(PY) -m pytest -q -m "paced and not slow" --built --durations=5

test-slow: venv $(FMU) $(SHIM) $(NATIVE) $(COMPILED)
	$(PY) -m pytest -q -m slow

build/bench/physics_bench: bench/physics_bench.c $(PLANT_SOURCES) | venv $(FMU)
	@mkdir -p build/bench
	$(CC) $(CFLAGS_BENCH) -Ibuild/plant/gen -Iplant/c -o $@ bench/physics_bench.c plant/c/quadrotor_physics.c -lm

# what one lockstep round trip costs the transport alone: a socket against a futex (bench/roundtrip.c)
build/bench/roundtrip: bench/roundtrip.c
	@mkdir -p build/bench
	$(CC) $(CFLAGS_BENCH) -o $@ bench/roundtrip.c

bench: venv $(FMU) $(SHIM) $(NATIVE) $(COMPILED) $(DUT_BIN) $(VBRIDGE) build/bench/physics_bench build/bench/roundtrip
	$(PY) bench/plant_rates.py
	$(PY) bench/emulator_rates.py
	$(PY) bench/exec_rates.py
	build/dut/bench_fc
	$(PY) bench/scenario_rates.py
	$(PY) bench/cycle_cost.py
	build/bench/roundtrip
	$(PY) bench/bridge_m4_cost.py
	$(PY) bench/bridge_rates.py
	$(PY) bench/sweep_rates.py

clean:
	rm -rf build

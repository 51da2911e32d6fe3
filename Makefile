# wdc: wave-digital compiler and sound runtime.
# `make` builds bin/wdc and bin/wdrt; `make demo` installs what is missing, builds,
# compiles every example netlist and renders it to out/; `make test` runs
# the test suite; `make bench` prints ns/sample of every example voice, then
# the speed and accuracy of each nonlinear one per solver and rate.

CC      ?= cc
CFLAGS  ?= -O2 -g
CFLAGS  += -std=c99 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -Wall -Wextra -pedantic -MMD -MP
LDLIBS  = -llapacke -lsndfile -lmysofa -ldl -lm

# the compiler: gen/ and the descriptors of the element kinds, blocks/
GEN_SRCS   = $(filter-out gen/main.c,$(wildcard gen/*.c)) $(wildcard blocks/*.c)
RT_SRCS    = $(filter-out runtime/wdrt_main.c,$(wildcard runtime/*.c))
TEST_LIB   = $(filter-out tests/test_%.c,$(wildcard tests/*.c))
TEST_SRCS  = $(wildcard tests/test_*.c)

GEN_OBJS   = $(GEN_SRCS:%.c=build/%.o) build/gen/templates.o
RT_OBJS    = $(RT_SRCS:%.c=build/%.o)
TLIB_OBJS  = $(TEST_LIB:%.c=build/%.o)
TEST_BINS  = $(TEST_SRCS:tests/%.c=build/tests/%)
NETLISTS   = $(wildcard netlists/*.wdn)
# tests built again under ThreadSanitizer, and under AddressSanitizer + UBSan
TSAN_BINS  = build/tests/test_storm_tsan build/tests/test_prepare_tsan
ASAN_BINS  = build/tests/test_engine_asan build/tests/test_scene_asan build/tests/test_tree_asan build/tests/test_treescene_asan build/tests/test_evolve_asan build/tests/test_surf_asan

all: bin/wdc bin/wdrt

build/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -iquote runtime -iquote gen -c $< -o $@

build/gen/templates.c: $(wildcard templates/*.tmpl) runtime/wdvoice.h scripts/embed.sh
	@mkdir -p $(dir $@)
	sh scripts/embed.sh $@ tmpl_voice_c=templates/voice.c.tmpl tmpl_voice_h=templates/voice.h.tmpl \
		tmpl_wdvoice_h=runtime/wdvoice.h tmpl_nl_diode_i=templates/nl_diode_i.c.tmpl tmpl_nl_wright=templates/nl_wright.c.tmpl tmpl_nl_diode=templates/nl_diode.c.tmpl tmpl_nl_omega=templates/nl_omega.c.tmpl tmpl_nl_fast=templates/nl_fast.c.tmpl tmpl_nl_fast_lane=templates/nl_fast_lane.c.tmpl \
		tmpl_nl_pwl=templates/nl_pwl.c.tmpl tmpl_nl_law=templates/nl_law.c.tmpl tmpl_nl_passive=templates/nl_passive.c.tmpl \
		tmpl_nl_memory=templates/nl_memory.c.tmpl tmpl_nl_g=templates/nl_g.c.tmpl tmpl_nl_joint=templates/nl_joint.c.tmpl tmpl_nl_memcap=templates/nl_memcap.c.tmpl tmpl_waveguide=templates/waveguide.c.tmpl \
		tmpl_waveguide_state=templates/waveguide_state.c.tmpl \
		tmpl_lu=templates/lu.c.tmpl tmpl_retune=templates/retune.c.tmpl tmpl_root=templates/root.c.tmpl tmpl_ctl_stamp=templates/ctl_stamp.c.tmpl \
		tmpl_nl_adapt=templates/nl_adapt.c.tmpl tmpl_settle=templates/settle.c.tmpl tmpl_params=templates/params.c.tmpl \
		tmpl_lv2_c=templates/lv2.c.tmpl tmpl_lv2_manifest=templates/lv2_manifest.ttl.tmpl \
		tmpl_lv2_plugin=templates/lv2_plugin.ttl.tmpl

build/gen/templates.o: build/gen/templates.c
	$(CC) $(CFLAGS) -c $< -o $@

build/libwdc.a: $(GEN_OBJS)
	ar rcs $@ $^

build/libwdrt.a: $(RT_OBJS)
	ar rcs $@ $^

bin/wdc: build/gen/main.o build/libwdc.a build/libwdrt.a
	@mkdir -p bin
	$(CC) $(CFLAGS) -o $@ $^ $(LDLIBS)

bin/wdrt: build/runtime/wdrt_main.o build/libwdrt.a
	@mkdir -p bin
	$(CC) $(CFLAGS) -o $@ $^ $(LDLIBS)

build/tests/%: build/tests/%.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lpthread

# The LV2 tests' plugin host (tests/lv2host), on lilv; test_lv2 runs it
# and bin/wdc, so both come first (order-only: they are not linked in).
LILV_CFLAGS = $(shell pkg-config --cflags lilv-0 2>/dev/null || echo -I/usr/include/lilv-0)
LILV_LIBS   = $(shell pkg-config --libs lilv-0 2>/dev/null || echo -llilv-0)

build/tests/lv2host: tests/lv2host/lv2host.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(LILV_CFLAGS) -o $@ $< $(LILV_LIBS) -lsndfile -lm

build/tests/test_lv2: | build/tests/lv2host bin/wdc

deps:
	sh scripts/install-deps.sh

demo: deps
	$(MAKE) all
	sh scripts/demo.sh

test: deps
	$(MAKE) run-tests

# The benchmarks' own C is compiled (not run) with the tests, so that it
# keeps building; the two that need faust's or OpenAL's headers are left
# to `make chart` and `make bench`.
BENCH_CHECK = $(filter-out build/bench/faustpeer.o build/bench/spacebench.o,$(patsubst bench/%.c,build/bench/%.o,$(wildcard bench/*.c)))

run-tests: all build/examples/embed $(TEST_BINS) $(TSAN_BINS) $(ASAN_BINS) $(BENCH_CHECK)
	sh tests/run.sh $(TEST_BINS) $(TSAN_BINS) $(ASAN_BINS)

# The runtime's tests again with the runtime and the test built under
# AddressSanitizer and UndefinedBehaviorSanitizer (leaks fail them too).
build/tests/%_asan: tests/%.c $(RT_SRCS) runtime/wdrt.h runtime/sexp.h $(TLIB_OBJS) build/libwdc.a
	@mkdir -p $(dir $@)
	$(CC) $(filter-out -MMD -MP,$(CFLAGS)) -fsanitize=address,undefined -fno-sanitize-recover=undefined \
		-fno-omit-frame-pointer -iquote runtime -iquote gen -o $@ $< $(RT_SRCS) $(TLIB_OBJS) build/libwdc.a -lcmocka $(LDLIBS) -lpthread

# examples/embed: an application that compiles a generated voice in, as
# an application would (no compiler, no dlopen at run time).
build/examples/piano_key/piano_key.c: scenes/piano_key.wdn blocks/piano.wdn bin/wdc
	bin/wdc scenes/piano_key.wdn -o build/examples/piano_key

build/examples/embed: examples/embed.c examples/score.h build/examples/piano_key/piano_key.c build/libwdrt.a
	$(CC) $(filter-out -MMD -MP,$(CFLAGS)) -iquote runtime -iquote build/examples/piano_key -o $@ examples/embed.c \
		build/examples/piano_key/piano_key.c build/libwdrt.a -lsndfile -lmysofa -lm

# The event storm again under ThreadSanitizer: the engine and the test
# built with -fsanitize=thread (the counting allocator steps aside).
build/tests/test_storm_tsan: tests/test_storm.c runtime/engine.c runtime/bodies.c runtime/surf.c runtime/wdrt.h $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	@mkdir -p $(dir $@)
	$(CC) $(filter-out -MMD -MP,$(CFLAGS)) -fsanitize=thread -iquote runtime -iquote gen -o $@ tests/test_storm.c runtime/engine.c runtime/bodies.c runtime/surf.c \
		$(TLIB_OBJS) build/libwdc.a build/libwdrt.a -lcmocka $(LDLIBS) -lpthread

# The prepared designs of the engine, posted from a thread of their own.
build/tests/test_prepare_tsan: tests/test_prepare.c runtime/engine.c runtime/wdrt.h $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	@mkdir -p $(dir $@)
	$(CC) $(filter-out -MMD -MP,$(CFLAGS)) -fsanitize=thread -iquote runtime -iquote gen -o $@ tests/test_prepare.c runtime/engine.c \
		$(TLIB_OBJS) build/libwdc.a build/libwdrt.a -lcmocka $(LDLIBS) -lpthread

bench: deps
	sh scripts/install-bench-deps.sh
	$(MAKE) all build/bench/bench build/bench/nlbench build/bench/deckbench build/bench/stkbench build/bench/rtbench build/bench/spacebench build/bench/treebench build/bench/surfbench build/bench/paramblock build/bench/compilebench
	build/bench/bench $(NETLISTS) tests/nets/idle_without.wdn tests/nets/idle_with.wdn tests/nets/hammers_one.wdn tests/nets/hammers_eight.wdn
	build/bench/nlbench $(NETLISTS)
	build/bench/deckbench netlists/*.cir netlists/diode_clipper.wdn
	build/bench/stkbench netlists/pluck.wdn
	build/bench/rtbench
	build/bench/spacebench
	build/bench/treebench
	build/bench/surfbench
	build/bench/paramblock $(NETLISTS)
	build/bench/compilebench

build/bench/bench: build/bench/bench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

build/bench/nlbench: build/bench/nlbench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

# The SPICE decks' voices: ns/sample, Newton steps of the joint solves, error against refsim.
build/bench/deckbench: build/bench/deckbench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

# What a param change costs the audio thread: inline, and with prepare off it.
build/bench/paramblock: build/bench/paramblock.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

# Compile time against netlist size: chains, ladders and trees of 10^3 to 10^5 elements.
build/bench/compilebench: build/bench/compilebench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

# The engine's economy: sleeping voices, a 1000-voice scene, an 88-key piano.
build/bench/rtbench: build/bench/rtbench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lpthread

# Timbre trees: the compiled program against the per-sample walk and hand C.
build/bench/treebench: build/bench/treebench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS)

# Bodies: one body in contact, 1000 bodies of which 10 are struck, sleeping bodies, the world's unit costs.
build/bench/surfbench: build/bench/surfbench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lpthread

# The spatial layer's cost per moving source, against OpenAL Soft (libopenal-dev).
build/bench/spacebench: build/bench/spacebench.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lopenal

# The plucked string against STK's Plucked (libstk-dev, through a C++ shim).
CXX     ?= g++
build/bench/stkshim.o: bench/stkshim.cpp
	@mkdir -p $(dir $@)
	$(CXX) -O2 -g -Wall -Wextra -pedantic -MMD -MP -c $< -o $@

build/bench/stkbench: build/bench/stkbench.o build/bench/stkshim.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lstk -lstdc++

# Speed against accuracy, our voices beside Faust's wdmodels.lib, STK and
# C written by hand, measured in one run (build/bench/chart) and drawn by
# gnuplot: out/chart.csv, out/chart.png, out/chart.svg.  The peers' C is
# compiled with the voices' flags; Faust's is made here from bench/faust/.
PEER_CFLAGS = -std=c99 -fPIC -O3 -march=native
FAUST_OBJS  = build/bench/faust/rc_lowpass_d.o build/bench/faust/rc_lowpass_f.o \
	build/bench/faust/diode_clipper_d.o build/bench/faust/diode_clipper_f.o

chart: deps
	sh scripts/install-chart-deps.sh
	$(MAKE) all build/bench/chart
	@mkdir -p out
	build/bench/chart -o out/chart.csv
	gnuplot -e "csv='out/chart.csv'; png='out/chart.png'; svg='out/chart.svg'" bench/chart.gp
	@echo "wrote out/chart.png and out/chart.svg"

build/bench/faust/%_d.c: bench/faust/%.dsp
	@mkdir -p $(dir $@)
	faust -lang c -double -cn $*_d $< -o $@

build/bench/faust/%_f.c: bench/faust/%.dsp
	@mkdir -p $(dir $@)
	faust -lang c -cn $*_f $< -o $@

build/bench/faust/%.o: build/bench/faust/%.c bench/faustpeer.c bench/peers.h
	$(CC) $(PEER_CFLAGS) -DFAUST_C='"$(CURDIR)/$<"' -DFAUST_CLASS=$* -iquote bench -c bench/faustpeer.c -o $@

build/bench/hand%.o: bench/hand%.c bench/peers.h
	@mkdir -p $(dir $@)
	$(CC) $(PEER_CFLAGS) -Wall -Wextra -pedantic -c $< -o $@

build/bench/chart: build/bench/chart.o build/bench/handrc.o build/bench/handclip.o $(FAUST_OBJS) build/bench/stkshim.o build/bench/benchlib.o $(TLIB_OBJS) build/libwdc.a build/libwdrt.a
	$(CC) $(CFLAGS) -o $@ $^ -lcmocka $(LDLIBS) -lstk -lstdc++
.PHONY: chart
.SECONDARY: $(FAUST_OBJS:.o=.c)

# Long fuzzing runs: the S-expression reader over 2 million mutated texts
# (about a minute; WDRT_FUZZ_SEED=N picks another sequence).
soak: build/tests/test_sexp build/tests/test_scene build/tests/test_tree
	WDRT_FUZZ_ITERS=2000000 build/tests/test_sexp
	WDRT_FUZZ_ITERS=200000 build/tests/test_scene
	WDRT_FUZZ_ITERS=200000 build/tests/test_tree
.PHONY: soak

format:
	clang-format -i gen/*.c gen/*.h blocks/*.c runtime/*.c runtime/*.h tests/*.c tests/*.h bench/*.c bench/*.h

clean:
	rm -rf build bin out

.PHONY: all deps demo test run-tests bench format clean
.PRECIOUS: build/tests/%.o build/%.o

-include $(shell find build -name '*.d' 2>/dev/null)

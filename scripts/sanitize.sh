#!/usr/bin/env bash
# The test suite (but for the tests left out below) under AddressSanitizer +
# UndefinedBehaviorSanitizer, in build-asan/ (or $PHONGFIT_ASAN_DIR). Fails on any test failure
# and on any sanitizer report, including reports from phongfit subprocesses whose tests only
# expected a failure: every report goes to a log file that must stay empty. -O2 (session 56: 25
# of the slowest sanitized tests in 582 s against 726 at -O1, the build no slower) and unity
# batches (as scripts/build.sh) keep it affordable on 2 cores; extra arguments go to ctest. Built
# with clang, as the fuzzers are: it compiles the sanitized Eigen and Ceres templates in 60% of
# gcc's time (fitter_test.cpp: 55 s against 91, side by side), and a second compiler sees what the
# plain (gcc) build does not.
#
# Left out, to keep CI under its 45 minutes (each takes 1-4 min under ASan; all run in the plain
# suite of scripts/test.sh):
# - the format check (label format: clang-format runs, none of our code; 46 s in session 81's CI);
# - the Slurm cluster test (label slurm: it runs the same commands as shard_command_test, through
#   daemons);
# - the two 128x128 Cornell round trips (RoundTrip.CornellBoxWithUnknownExposure and
#   ...FromAStartWithNOffBy100x), whose code paths (recording, replay, Ceres rounds, the exposure)
#   run under ASan in the smaller Cornell round trip and
#   RoundTrip.DirectLightLeavesTheExposureUnconstrained;
# - statistical checks that repeat code paths other tests run under ASan:
#   RoundTrip.AreaLightSharpLobeIsFoundWithAdaptivePaths and RoundTrip/SubPixelHighlight.*
#   (area light, adaptive paths and holding: the small Cornell box and the exponent grid),
#   Bench.RecoveryMatrixSubsetPassesAtDefaults (bench fit: Bench.FitRecoversTheSmallDataset and the
#   sharded bench), DiligentBall.ExponentIsStableBetweenOddAndEvenLights (the capture fit: the
#   other DiligentBall and AlbedoMap tests),
#   RoundTrip/HighlightPixelNoise.* (149 s and 116 s under ASan in session 81's CI, 148 s for
#   seed "1" alone in session 82's, 11-13 s without: mostly its 256x256 image at 256 Sobol
#   samples; the pixels rendered anew as the scene renders them run under ASan in
#   FitMemory.PixelsRenderedAnewAddNothingToThePeak and
#   RoundTrip.ASharperLobeTheImageDoesNotRuleOutIsWithinTheStandardErrors),
#   RoundTrip.ASubPixelHighlightsNoiseWhereTheLobeIsSharperReachesIt (41 s: the sharper lobes'
#   noise, sharperReach, runs under ASan in ...ASharperLobeTheImageDoesNotRuleOut..., which calls
#   it before imageReach) and EdgeAgreementTest.ATentFilteredCornellBoxNamesItsFilter (33 s: the
#   edge check's filter search runs under ASan in the other EdgeAgreementTest cases),
#   Synth.ResumesAfterSigintWithTheSameFilesAsAnUninterruptedRun (synth's interrupt and resume:
#   FitSynthInterrupt.SynthKeepsFinishedSamplesAndResumes),
#   ImageNoise.APixelThatHoldsTheLobeBringsItsNoiseIntoTheStandardErrors (52 s under ASan, 1.7 s
#   without: the image-noise model runs in every fit on noisy recordings, e.g.
#   Fitter.RoundsOnFreshNoisyPathSetsConvergeToTheTruth and the small Cornell round trip);
# - the demo (FitCommand.DemoRendersFitsBackAndPrintsTheErrors, the longest test under ASan: 2.5-4
#   min, its 16-spp image growing the paths 16x): a Cornell render and scene fit, the paths' growth
#   to the noise floor and the sharper probe, which run under ASan in
#   RoundTrip.SmallCornellBoxStaysWithinItsStandardErrors,
#   RoundTrip.PrecisionTargetSpendsPathsUntilMetOrAtTheImagesNoiseFloor and
#   RoundTrip.SphereUnderTheKernerProbeIsRecovered.
# - the longest round trips under ASan (session 40's CI: 295 s and 208 s, the run 2623 s of its 45
#   minutes): RoundTrip.TungstenRendersOfTheQuadLitSphereAreRecovered (three quad-lit fits on
#   Tungsten's images: Tungsten's EXR and the area light's rounds run under ASan in
#   RoundTrip.TungstenPointLitSharpLobeIsRecovered and ...LobeHeldByPixelsAtTheirPathCapEndsThere)
#   and RoundTrip.ClimbThatSettlesShortOfTheLobeHasItsSharperSideProbed (two climbs over a
#   sampled area light; the precision target's growth, the drift's widening and the last round's
#   probe run in the fitter tests, e.g. Fitter.RoundsThatDoNotSettleRecordMorePaths).
# - the two ringed round trips at 1024 spp (session 47: 297 s and 94 s under ASan, the run 2914 s):
#   RoundTrip.RingsSayASubPixelLobesExponentIsNotHeld (three fits, most of it their renders) and
#   ...GrownRoundsOfRingedRecordingsKeepTheRingsPrecision: ringed rounds over the 40-degree light
#   run under ASan in ...LobeHeldByPixelsAtTheirPathCapEndsThere, the weighting of ringed and
#   sampled paths in ReplayAgainstRender.RingsUnderAPartlyHiddenLightMatchTheRender and the
#   PathSetFilm tests.
# - three that are 12-14x their plain time under ASan (session 55's CI: 166, 136 and 107 s, the run
#   3077 s): LightRings.TheLobeMatchesAPolarGridFromN1To1e6 (its time is the test's own 3000^2-cell
#   quadrature; the rings run under ASan in the other LightRings tests and
#   ReplayAgainstRender.RingsUnderAPartlyHiddenLightMatchTheRender),
#   RoundTrip.ClimbThatSettlesInTheLastRoundIsNotConverged (a 1024-path render and six rounds: a
#   sampled area light's recordings run under ASan in the small Cornell round trip, the "sharper
#   lobe" stop in Fitter.ProbeThatDoesNotComeBackInTheLastRoundLeavesTheConvergedEstimateUnvouched)
#   and FitMemory.StateBeyondImagesAndPathsIsAtMostTheBoundPerUsedPixel (the fit of
#   FitMemory.StateStaysWithinTheBoundWhenMostPixelsAreLeftOut with the walls' pixels kept, 8x the
#   pixels; the walls' pixels are kept under ASan in
#   SceneFitPixels.PixelsThatSeeTheMaterialOnlyIndirectlyAreLeftOut).
# - RoundTrip.AFaintBroadLobeIsFoundFromASharpStart (session 61's CI: 202 s under ASan, 20 s
#   without, the run 2806 s; most of it the 256x256 envmap render it must match bit for bit): the
#   envmap's render and recording run under ASan in RoundTrip.SphereUnderTheKernerProbeIsRecovered,
#   and the start scan's cross-products comparison (crossSignificant, 24 of them) in
#   Fitter.DoesNotDependOnTheThreadCount.
# - RoundTrip.NoLobeUnderTheProbeMeetsThePrecisionOfItsAlbedo (session 89's CI: 24-38 s under
#   ASan, 6.7 s without): the ks of no lobe asked relative to the albedo runs under ASan in
#   PrecisionTarget.TheKsOfNoLobeIsAskedRelativeToTheAlbedo, the probe's render and rounds in
#   RoundTrip.SphereUnderTheKernerProbeIsRecovered.
# - the analytic sphere's two high-spp cases (session 57's CI: 37 s and 22 s, the run 2399 s):
#   Materials/AnalyticSphere.InteriorPixelsMatchTheBoxFilteredClosedForm/n5000_spp4096 and
#   .../n300_spp2048, the same comparison as its three 256-spp cases, which run under ASan.
# $SANITIZE_EXCLUDE, a ctest regex, replaces that list for a local run ("" leaves none out).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${PHONGFIT_ASAN_DIR:-$root/build-asan}
jobs=$(nproc)

"$root/scripts/setup.sh"
flags="-O2 -g1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all"
# Eigen switches to its own aligned allocator under ASan, but libceres (not rebuilt) frees with
# plain free what it allocated, and the other way round: keep glibc's (16-byte aligned) malloc.
flags+=" -DEIGEN_MALLOC_ALREADY_ALIGNED=1"
# A build directory configured with another compiler (gcc, before) cannot switch: start it anew.
if [[ -f $build/CMakeCache.txt ]] && ! grep -q '^CMAKE_CXX_COMPILER:.*clang++' "$build/CMakeCache.txt"; then
  rm -rf "$build"
fi
CXX=clang++ cmake -S "$root" -B "$build" -G "Unix Makefiles" -DCMAKE_BUILD_TYPE=Sanitize \
  -DCMAKE_UNITY_BUILD=ON -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
# The tests folder's targets and what they depend on (the phongfit binary); benchmarks are not run.
make -C "$build/tests" -j "$jobs" --no-print-directory
# The round trips render the images they fit with the plain build (scripts/build.sh) where there
# is one: its renders are the same to the bit and 6-7 times faster than the sanitized build's, which
# took 40-45% of the round trips' time under ASan (session 83: 632 s of round trips -> 342 s). The
# renderer runs under the sanitizers in its own tests, the render command's, and every fit's
# recording.
plain=${PHONGFIT_BUILD_DIR:-$root/build}
if [[ -f $plain/CMakeCache.txt ]]; then
  cmake --build "$plain" --target phongfit -- --no-print-directory
  export PHONGFIT_TEST_RENDER_EXE=$plain/phongfit
fi

reports="$build/sanitizer-reports"
rm -rf "$reports"
mkdir -p "$reports"
export ASAN_OPTIONS="log_path=$reports/asan:detect_leaks=1:strict_string_checks=1:check_initialization_order=1"
export UBSAN_OPTIONS="log_path=$reports/ubsan:print_stacktrace=1:halt_on_error=1"

status=0
slow='RoundTrip.CornellBoxWithUnknownExposure|RoundTrip.CornellBoxFromAStartWithNOffBy100x'
slow+='|RoundTrip.AreaLightSharpLobeIsFoundWithAdaptivePaths|RoundTrip/SubPixelHighlight\.'
slow+='|Bench.RecoveryMatrixSubsetPassesAtDefaults|DiligentBall.ExponentIsStableBetweenOddAndEvenLights'
slow+='|Synth.ResumesAfterSigintWithTheSameFilesAsAnUninterruptedRun'
slow+='|ImageNoise.APixelThatHoldsTheLobeBringsItsNoiseIntoTheStandardErrors'
slow+='|RoundTrip/HighlightPixelNoise\.|RoundTrip.ASubPixelHighlightsNoiseWhereTheLobeIsSharperReachesIt'
slow+='|EdgeAgreementTest.ATentFilteredCornellBoxNamesItsFilter'
slow+='|FitCommand.DemoRendersFitsBackAndPrintsTheErrors'
slow+='|RoundTrip.TungstenRendersOfTheQuadLitSphereAreRecovered'
slow+='|RoundTrip.ClimbThatSettlesShortOfTheLobeHasItsSharperSideProbed'
slow+='|RoundTrip.RingsSayASubPixelLobesExponentIsNotHeld'
slow+='|RoundTrip.GrownRoundsOfRingedRecordingsKeepTheRingsPrecision'
slow+='|LightRings.TheLobeMatchesAPolarGridFromN1To1e6'
slow+='|RoundTrip.ClimbThatSettlesInTheLastRoundIsNotConverged'
slow+='|FitMemory.StateBeyondImagesAndPathsIsAtMostTheBoundPerUsedPixel'
slow+='|RoundTrip.AFaintBroadLobeIsFoundFromASharpStart'
slow+='|RoundTrip.NoLobeUnderTheProbeMeetsThePrecisionOfItsAlbedo'
slow+='|AnalyticSphere.InteriorPixelsMatchTheBoxFilteredClosedForm/(n5000_spp4096|n300_spp2048)'
exclude=${SANITIZE_EXCLUDE-$slow}
(cd "$build" && ctest --output-on-failure -j "$jobs" --timeout 900 -LE "slurm|format" \
  ${exclude:+-E "$exclude"} "$@") ||
  status=$?
if compgen -G "$reports/*" >/dev/null; then
  echo "sanitize: sanitizer reports:" >&2
  for f in "$reports"/*; do
    echo "==> $f" >&2
    cat "$f" >&2
  done
  status=1
fi
if ((status != 0)); then
  echo "sanitize: FAILED" >&2
  exit "$status"
fi
echo "sanitize: all tests passed with no sanitizer report"

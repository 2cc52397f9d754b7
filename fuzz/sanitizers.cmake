# Included by the top-level CMakeLists.txt before any target when MLCLUST_BUILD_FUZZERS is
# ON: every target of the build (the core layers the fuzzers link included) is compiled
# with libFuzzer's coverage instrumentation, AddressSanitizer and UndefinedBehaviorSanitizer,
# so a fault anywhere in our code stops the fuzzer. Libraries from the system (Abseil,
# Draco, Assimp, protobuf) are linked as they are: ASan still checks the memory they touch
# through our calls, but libFuzzer gets no coverage from inside them.
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "MLCLUST_BUILD_FUZZERS needs clang (libFuzzer), e.g. "
                      "CC=clang-14 CXX=clang++-14; got ${CMAKE_CXX_COMPILER_ID}")
endif()
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all
                    -fno-omit-frame-pointer -g)
add_link_options(-fsanitize=address,undefined)

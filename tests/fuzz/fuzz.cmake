# Fuzz targets: one fuzz_<name>.c per parser with LLVMFuzzerTestOneInput and
# a seed corpus in corpus/<name>/. Every build replays the corpus through
# the same function in ctest (replay_<name>); with -DGI_FUZZ=ON (clang,
# `make fuzz`) each also becomes a libFuzzer binary fuzz_<name>.
# Adding a target: write fuzz_<name>.c, add corpus/<name>/, call gi_add_fuzz
# (with SOURCES and LIBS when the parser is not in gicore).
option(GI_FUZZ "build libFuzzer targets (needs clang)" OFF)

function(gi_add_fuzz name)
  cmake_parse_arguments(F "" "" "SOURCES;LIBS;INCLUDES" ${ARGN})
  add_executable(replay_${name} fuzz/fuzz_${name}.c fuzz/replay.c ${F_SOURCES})
  target_link_libraries(replay_${name} PRIVATE ${F_LIBS} gicore)
  target_include_directories(replay_${name} PRIVATE ${F_INCLUDES})
  set_target_properties(replay_${name} PROPERTIES LINKER_LANGUAGE CXX
                        RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  add_test(NAME fuzz_replay_${name} COMMAND replay_${name} ${CMAKE_CURRENT_SOURCE_DIR}/fuzz/corpus/${name})
  set_tests_properties(fuzz_replay_${name} PROPERTIES TIMEOUT 300)
  if(GI_FUZZ)
    add_executable(fuzz_${name} fuzz/fuzz_${name}.c ${F_SOURCES})
    target_link_libraries(fuzz_${name} PRIVATE ${F_LIBS} gicore)
    target_include_directories(fuzz_${name} PRIVATE ${F_INCLUDES})
    target_link_options(fuzz_${name} PRIVATE -fsanitize=fuzzer)
    set_target_properties(fuzz_${name} PROPERTIES LINKER_LANGUAGE CXX
                          RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fuzz)
  endif()
endfunction()

gi_add_fuzz(scene)
gi_add_fuzz(request LIBS giproto)
# The config loader is server/config.c, built into the target (the server is a program, not a library).
gi_add_fuzz(config SOURCES ${CMAKE_SOURCE_DIR}/server/config.c LIBS giproto PkgConfig::INIH
            INCLUDES ${CMAKE_SOURCE_DIR}/server)
# As for gi-server: its messages may cut a long path short (values never are).
target_compile_options(replay_config PRIVATE -Wno-format-truncation)
if(GI_FUZZ)
  target_compile_options(fuzz_config PRIVATE -Wno-format-truncation)
endif()

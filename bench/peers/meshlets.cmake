# meshlets_bench (bench/peers/meshlets_bench.cc): ours against meshoptimizer's
# meshopt_buildMeshlets and METIS k-way. Included from bench/CMakeLists.txt: it links
# mlclust_core, so it is built with the product rather than in build-peers. Each peer is
# compiled in only where its Debian package was found (libmeshoptimizer-dev, libmetis-dev:
# scripts/install-deps.sh --bench); without them the bench runs ours alone.
add_executable(meshlets_bench ${CMAKE_CURRENT_LIST_DIR}/meshlets_bench.cc)
target_link_libraries(meshlets_bench PRIVATE mlclust_core absl::time absl::strings)
find_package(meshoptimizer CONFIG QUIET)
if(meshoptimizer_FOUND)
  target_link_libraries(meshlets_bench PRIVATE meshoptimizer::meshoptimizer)
  target_compile_definitions(meshlets_bench PRIVATE MLCLUST_HAVE_MESHOPTIMIZER)
endif()
find_path(MLCLUST_METIS_INCLUDE_DIR metis.h)
find_library(MLCLUST_METIS_LIBRARY metis)
if(MLCLUST_METIS_INCLUDE_DIR AND MLCLUST_METIS_LIBRARY)
  target_include_directories(meshlets_bench PRIVATE ${MLCLUST_METIS_INCLUDE_DIR})
  target_link_libraries(meshlets_bench PRIVATE ${MLCLUST_METIS_LIBRARY})
  target_compile_definitions(meshlets_bench PRIVATE MLCLUST_HAVE_METIS)
endif()
message(STATUS "meshlets_bench peers: meshoptimizer ${meshoptimizer_FOUND}, METIS "
               "${MLCLUST_METIS_LIBRARY}")

# meshlets_caps_bench (bench/peers/meshlets_caps_bench.cc): capped meshlets, ours
# (core/meshlets) against meshopt_buildMeshlets at the same caps and METIS k-way.
add_executable(meshlets_caps_bench ${CMAKE_CURRENT_LIST_DIR}/meshlets_caps_bench.cc)
target_link_libraries(meshlets_caps_bench PRIVATE mlclust_core absl::time absl::strings)
if(meshoptimizer_FOUND)
  target_link_libraries(meshlets_caps_bench PRIVATE meshoptimizer::meshoptimizer)
  target_compile_definitions(meshlets_caps_bench PRIVATE MLCLUST_HAVE_MESHOPTIMIZER)
endif()
if(MLCLUST_METIS_INCLUDE_DIR AND MLCLUST_METIS_LIBRARY)
  target_include_directories(meshlets_caps_bench PRIVATE ${MLCLUST_METIS_INCLUDE_DIR})
  target_link_libraries(meshlets_caps_bench PRIVATE ${MLCLUST_METIS_LIBRARY})
  target_compile_definitions(meshlets_caps_bench PRIVATE MLCLUST_HAVE_METIS)
endif()

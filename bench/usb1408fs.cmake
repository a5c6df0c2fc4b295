# USB-1408FS benchmarks against the simulated board. Included from bench/CMakeLists.txt with
# include(${CMAKE_CURRENT_LIST_DIR}/usb1408fs.cmake); run build/bench/bench_usb.
add_executable(bench_usb ${CMAKE_CURRENT_LIST_DIR}/bench_usb.cpp)
target_link_libraries(bench_usb PRIVATE zerocal::usb1408fs zerocal::sim_usb1408fs zerocal::sim_psd
                      zerocal::sim_psd_rig zerocal::psd zerocal::servo zerocal::usb1408fs_readout benchmark::benchmark
                      zerocal::warnings)

// Benchmark: the change stage of process_flight alone (flight::CompareFlights,
// issue 35) on two DEMs it wrote, so that the error model of the DoD can be
// compared without orienting and matching the flights again
// (bench/real_flight_change/run.sh writes them). Prints, for one global LoD
// and for the heteroscedastic model with each bin spread (NMAD, quantile):
// median dz and NMAD on stable ground, the share of stable cells flagged
// (all, and held out by the two-fold checkerboard check) and the model's bins.
//
//   bench_flight_change REFERENCE_SURFACE.tif LATER_SURFACE.tif
//
// Both DEMs on one grid, in one CRS; no site areas: every common cell is
// stable ground (as process_flight without a site file).
#include <cstdio>
#include <exception>
#include <string>

#include "slope_monitor/core/flight/flight_surface.h"
#include "slope_monitor/core/io/geotiff.h"

using namespace slope_monitor;

int main(int argc, char** argv) {
  if (argc != 3 || std::string(argv[1]) == "--help") {
    std::fprintf(stderr, "usage: bench_flight_change REFERENCE_SURFACE.tif LATER_SURFACE.tif\n");
    return argc == 2 ? 0 : 1;
  }
  try {
    const io::GeoRaster ref = io::ReadGeoTiff(argv[1]), after = io::ReadGeoTiff(argv[2]);
    flight::FlightChangeInput in;
    in.reference = &ref;
    in.after = &after;
    struct Variant {
      const char* name;
      bool model;
      dense::ErrorModelOptions::Spread spread;
    };
    const Variant variants[] = {
        {"global LoD", false, dense::ErrorModelOptions::Spread::kNmad},
        {"model, NMAD", true, dense::ErrorModelOptions::Spread::kNmad},
        {"model, quantile", true, dense::ErrorModelOptions::Spread::kQuantile}};
    for (const Variant& v : variants) {
      flight::FlightChangeOptions o;
      o.change.error_model.enabled = v.model;
      o.change.error_model.spread = v.spread;
      const flight::FlightChange c = flight::CompareFlights(in, o);
      const flight::FlightChangeSummary& s = c.summary;
      std::printf("%s: median dz %.4f m, NMAD %.4f m, flagged %.2f %% of %d stable cells", v.name,
                  s.stable_median, s.stable_nmad, 100 * s.stable_flagged, s.stable_common);
      if (v.model)
        std::printf(", held out %.2f %% of %d (block %.2f m)", 100 * s.dem.holdout_flagged,
                    s.dem.holdout_cells, s.dem.holdout_block);
      std::printf("; sigma_extra %.4f m, L %.2f m\n", s.dem.sigma_extra,
                  s.dem.coregistration.correlation_length);
      for (const dense::ErrorBin& b : s.dem.error_model.bins)
        std::printf(
            "  slope %5.1f .. %5.1f deg, roughness %.3f .. %.3f m: %5d cells, median "
            "%+.4f m, sigma %.4f m\n",
            b.slope_min, b.slope_max, b.roughness_min, b.roughness_max, b.cells, b.median, b.sigma);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_flight_change: %s\n", e.what());
    return 2;
  }
  return 0;
}

// The peer in scripts/cgal-peer.sh: CGAL's optimal-transport curve reconstruction
// (de Goes et al. 2011) on a point file. Reads `x y` lines, decimates the Delaunay
// triangulation of the points until the Wasserstein tolerance given as the second
// argument is reached, and writes the kept edges as `x1 y1 x2 y2` lines to stdout and
// the reconstruction's milliseconds (reading excluded) to stderr.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Optimal_transportation_reconstruction_2.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <iterator>
#include <vector>

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_2;
using Segment = K::Segment_2;
using Otr = CGAL::Optimal_transportation_reconstruction_2<K>;

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: otr2 POINTS.xy TOLERANCE\n";
    return 2;
  }
  std::ifstream in(argv[1]);
  if (!in) {
    std::cerr << "cannot read " << argv[1] << "\n";
    return 1;
  }
  std::vector<Point> points;
  double x, y;
  while (in >> x >> y) points.emplace_back(x, y);
  const double tolerance = std::atof(argv[2]);
  auto t0 = std::chrono::steady_clock::now();
  Otr otr(points);
  otr.run_under_wasserstein_tolerance(tolerance);
  std::vector<Point> isolated;
  std::vector<Segment> edges;
  otr.list_output(std::back_inserter(isolated), std::back_inserter(edges));
  auto ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::cout.precision(10);
  for (const Segment& s : edges)
    std::cout << s.source().x() << ' ' << s.source().y() << ' ' << s.target().x() << ' '
              << s.target().y() << '\n';
  std::cerr << ms << "\n";
  return 0;
}

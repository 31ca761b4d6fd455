// ViSP's model-based edge tracker (vpMbEdgeTracker, moving edges) run over a
// pipetrack sequence's frames, writing pipetrack's prediction lines, so that
// `pipetrack score` scores it as it scores pipetrack's own trackers.
//
//   edge_tracker FRAMES MODEL.cao VERTICES OUT.jsonl px py u0 v0 tx ty tz rx ry rz
//                [--settings SETTINGS.xml] [--overlay DIR]
//
// FRAMES     folder of the frames 000000.png, 000001.png, ... (a sequence's frames/)
// MODEL.cao  the model in ViSP's format
// VERTICES   the model's vertices in pipetrack's order, one "x y z" (metres) per
//            line: each line's `corners` are these projected with the frame's pose
//            ("-": none, for a sequence without truth to score against)
// px .. v0   the camera intrinsics (pixels)
// tx .. rz   the first frame's pose cMo: translation (m) and axis-angle (rad)
// SETTINGS   ViSP tracker settings (moving edges, clipping, camera); without
//            them the tracker keeps ViSP's defaults
// DIR        an existing folder for overlays: each frame with the visible model
//            drawn in red at the pose tracked, DIR/NNNNNN.png
//
// A frame is "lost" when vpMbEdgeTracker::track throws (ViSP's only sign of
// failure; the next frame is tracked on from the pose it keeps), "tracking"
// otherwise; `ms` is the time of track alone (frame reading and output
// excluded). Run it with
// OMP_NUM_THREADS=1 for one thread. Exit status 2 on bad arguments or files.
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImage.h>
#include <visp3/core/vpImageConvert.h>
#include <visp3/core/vpImageDraw.h>
#include <visp3/core/vpPoseVector.h>
#include <visp3/io/vpImageIo.h>
#include <visp3/mbt/vpMbEdgeTracker.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Vertex {
    double x, y, z;
};

std::vector<Vertex> read_vertices(const std::string &path) {
    if (path == "-") return {};
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open");
    std::vector<Vertex> vertices;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream fields(line);
        Vertex v;
        if (fields >> v.x >> v.y >> v.z) vertices.push_back(v);
    }
    if (vertices.empty()) throw std::runtime_error(path + ": no vertices");
    return vertices;
}

std::string frame_path(const std::string &folder, int k) {
    char name[32];
    std::snprintf(name, sizeof name, "/%06d.png", k);
    return folder + name;
}

// Frame `image` with the model's visible edges at `cMo` drawn in red, as
// DIR/NNNNNN.png.
void write_overlay(const std::string &folder, int k, const vpImage<unsigned char> &image, vpMbEdgeTracker &tracker,
                   const vpHomogeneousMatrix &cMo, const vpCameraParameters &cam) {
    vpImage<vpRGBa> colour;
    vpImageConvert::convert(image, colour);
    // Each entry: 0 for a line, then its ends as (row, column) pairs.
    for (const std::vector<double> &line : tracker.getModelForDisplay(image.getWidth(), image.getHeight(), cMo, cam)) {
        if (line.size() >= 5 && line[0] == 0) {
            vpImageDraw::drawLine(colour, vpImagePoint(line[1], line[2]), vpImagePoint(line[3], line[4]), vpColor::red);
        }
    }
    vpImageIo::write(colour, frame_path(folder, k));
}

bool exists(const std::string &path) { return std::ifstream(path).good(); }

// One output line: the pose and every vertex projected with it.
void write_line(std::ostream &out, int k, bool tracking, const vpHomogeneousMatrix &cMo, const std::vector<Vertex> &vertices,
                const vpCameraParameters &cam, double ms) {
    const vpPoseVector pose(cMo);
    out.precision(10);
    out << "{\"frame\":" << k << ",\"status\":\"" << (tracking ? "tracking" : "lost") << "\",\"corners\":[";
    for (size_t i = 0; i < vertices.size(); ++i) {
        const Vertex &v = vertices[i];
        const double xc = cMo[0][0] * v.x + cMo[0][1] * v.y + cMo[0][2] * v.z + cMo[0][3];
        const double yc = cMo[1][0] * v.x + cMo[1][1] * v.y + cMo[1][2] * v.z + cMo[1][3];
        const double zc = cMo[2][0] * v.x + cMo[2][1] * v.y + cMo[2][2] * v.z + cMo[2][3];
        const double u = cam.get_u0() + cam.get_px() * xc / zc;
        const double w = cam.get_v0() + cam.get_py() * yc / zc;
        out << (i ? "," : "") << "[" << u << "," << w << "]";
    }
    out << "],\"pose\":{\"rotation\":[" << pose[3] << "," << pose[4] << "," << pose[5] << "],\"translation\":["
        << pose[0] << "," << pose[1] << "," << pose[2] << "]},\"ms\":" << ms << "}\n";
}

}  // namespace

int main(int argc, char **argv) {
    std::string settings, overlay;
    for (int i = 15; i + 1 < argc; i += 2) {
        const std::string option = argv[i];
        if (option == "--settings") {
            settings = argv[i + 1];
        } else if (option == "--overlay") {
            overlay = argv[i + 1];
        } else {
            argc = 0;
        }
    }
    if (argc < 15 || argc % 2 == 0) {
        std::cerr << "usage: edge_tracker FRAMES MODEL.cao VERTICES OUT.jsonl px py u0 v0 tx ty tz rx ry rz "
                     "[--settings SETTINGS.xml] [--overlay DIR]\n";
        return 2;
    }
    const std::string frames = argv[1], model = argv[2], vertices_file = argv[3], out_file = argv[4];
    double a[10];
    for (int i = 0; i < 10; ++i) {
        char *end = nullptr;
        a[i] = std::strtod(argv[5 + i], &end);
        if (end == argv[5 + i] || *end != '\0' || !std::isfinite(a[i])) {
            std::cerr << "edge_tracker: argument " << 5 + i << " is not a number: " << argv[5 + i] << "\n";
            return 2;
        }
    }
    try {
        const std::vector<Vertex> vertices = read_vertices(vertices_file);
        vpMbEdgeTracker tracker;
        vpCameraParameters cam(a[0], a[1], a[2], a[3]);
        if (!settings.empty()) tracker.loadConfigFile(settings, false);
        tracker.setCameraParameters(cam);
        tracker.loadModel(model);
        const vpHomogeneousMatrix start(vpPoseVector(a[4], a[5], a[6], a[7], a[8], a[9]));

        std::ofstream out(out_file);
        if (!out) throw std::runtime_error(out_file + ": cannot create");
        vpImage<unsigned char> image;
        for (int k = 0; exists(frame_path(frames, k)); ++k) {
            vpImageIo::read(image, frame_path(frames, k));
            double ms = 0.0;
            bool tracking = true;
            if (k == 0) {
                tracker.initFromPose(image, start);
            } else {
                const auto t0 = std::chrono::steady_clock::now();
                try {
                    tracker.track(image);
                } catch (const vpException &) {
                    // ViSP gives up on this frame (too few moving edges, a
                    // pose that does not converge): a loss, tracked on from
                    // the pose it keeps.
                    tracking = false;
                }
                ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
            }
            vpHomogeneousMatrix cMo;
            tracker.getPose(cMo);
            write_line(out, k, tracking, cMo, vertices, cam, ms);
            if (!overlay.empty()) write_overlay(overlay, k, image, tracker, cMo, cam);
        }
    } catch (const std::exception &e) {
        std::cerr << "edge_tracker: " << e.what() << "\n";
        return 2;
    }
    return 0;
}

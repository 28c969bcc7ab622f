// A plain single-threaded C++ implementation of one CEM guidance step, the yardstick for
// swarmscene's compiled CEM kernel (benchmarks/speed/peers/bench_cem_cpp.py builds and runs it).
//
// Romano, Uppaluru, Rastgoftar, Atkins, "Quadrotor Formation Flying Resilient to Abrupt Vehicle
// Failures via a Fluid Flow Navigation Function" (papers/cem-fluid-flow-navigation.md), written here
// from the paper for ONE failed vehicle (the six-vehicle scenario of section V-A):
//   f(z) = (z - z_f) + a_p^2 / (z - z_f)                    eq. 1-2 (phi + j psi)
//   Algorithm 2 (CalcXY): n Newton steps z <- z - (f(z) - w) / f'(z) (eq. 5 as a complex division)
//                         plus the saddle noise of eq. 6 as printed: every iteration whose estimate
//                         has |z - z_f| <= a_p gets |N(0, sigma)| r_a + N(0, sigma) r_b, r_b = -j r_a
//   Algorithm 1 (one tick): K passes of phi = phi_last + dphi, CalcXY, dphi *= v_des / v_max.
// With the same choices swarmscene makes where the paper is open (methods/cem/flow.py): every
// pass starts Newton from the previous tick's command, Newton stops early once every update is
// below 1e-10 m and no noise was drawn, and a branch guard moves a command that ended inside the
// disk out through the circle (mirror a_p^2 / u or radial a_p^2 / conj(u), whichever is nearer its
// start; a non-finite estimate restarts from its start plus eq. 6's noise).
//
// Normal draws come from a pool of pre-drawn N(0, 1) numbers read with the input (consumed in the
// order swarmscene draws them: per noisy iteration first every |N| term, then every N term), so the
// check mode can feed exactly the numbers the Python run drew; the timing loop cycles the pool,
// which leaves the random-number generation itself out of the C++ figure (in its favour).
// Complex quotients are written out (Smith's method) rather than std::complex's operator/, whose
// library call (__divdc3, with its inf/nan handling) a hand-tuned C++ loop would avoid too.
//
// Usage:  cem_reference time  INPUT TICKS REPEATS   -> "ns_per_step <wall> cpu_ns_per_step <cpu> ... checksum <sum>"
//         cem_reference check INPUT                 -> per tick: command, velocity, dphi, draws
// INPUT is whitespace-separated text written by bench_cem_cpp.py (see read_problem / read_check).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <time.h>
#include <vector>

using cd = std::complex<double>;

namespace {

struct Params {
    double a_p = 1.36, sigma = 1e-3, v_des = 1.0, dT = 0.01;
    int K = 2, n = 20;
    cd z_f{0.0, 0.0}, rot{1.0, 0.0}, origin{0.0, 0.0};
};

struct NormalPool {  // pre-drawn N(0, 1) numbers, consumed in order (cycled when timing)
    std::vector<double> values;
    size_t next = 0;
    double draw() { return values[next++ % values.size()]; }
};

constexpr double kNewtonTol = 1e-10;  // m

inline cd divide(cd a, cd b) {  // a / b, Smith's method
    const double br = b.real(), bi = b.imag();
    if (std::fabs(br) >= std::fabs(bi)) {
        const double rat = bi / br, scl = 1.0 / (br + bi * rat);
        return {(a.real() + a.imag() * rat) * scl, (a.imag() - a.real() * rat) * scl};
    }
    const double rat = br / bi, scl = 1.0 / (bi + br * rat);
    return {(a.real() * rat + a.imag()) * scl, (a.imag() * rat - a.real()) * scl};
}

inline bool finite(cd z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

// Eq. 6 for the estimates listed in idx (u = r - r_f at the estimate the Jacobian was evaluated at).
void kick(std::vector<cd>& z, const std::vector<cd>& u, const std::vector<int>& idx, double sigma,
          NormalPool& pool, std::vector<double>& g) {
    const size_t count = idx.size();
    g.resize(2 * count);
    for (size_t k = 0; k < 2 * count; ++k) g[k] = pool.draw() * sigma;
    for (size_t k = 0; k < count; ++k) {
        const int i = idx[k];
        const cd ra = u[i] / std::abs(u[i]);                // r_a: away from the failed vehicle
        z[i] += ra * cd(std::fabs(g[k]), -g[count + k]);    // |N| r_a + N r_b, r_b = -j r_a
    }
}

struct Navigator {
    Params p;
    std::vector<cd> z, z_prev, z_start, dz, w, wt, u, pos, vel;
    std::vector<double> g;
    std::vector<int> idx;
    double dphi = 0.0, used = 0.0;
    int iterations = 0;

    Navigator(const Params& prm, const std::vector<cd>& z0, const std::vector<cd>& w0)
        : p(prm), z(z0), z_prev(z0), z_start(z0), dz(z0.size()), w(w0), wt(w0), u(z0.size()),
          pos(z0.size()), vel(z0.size()), dphi(prm.v_des * prm.dT) {}

    // Algorithm 2 lines 3-8 for every agent, then the branch guard.
    void calc_xy(NormalPool& pool) {
        const size_t m = z.size();
        const double a = p.a_p, a2 = a * a;
        z_start = z;
        int it = 0;
        for (it = 0; it < p.n; ++it) {
            double worst = 0.0;
            idx.clear();
            for (size_t i = 0; i < m; ++i) {
                u[i] = z[i] - p.z_f;
                const cd v = divide(1.0, u[i]);
                const cd f = u[i] + a2 * v;               // eq. 1 (z_f is the flow's centroid)
                const cd fp = 1.0 - a2 * v * v;           // f'(z) = phi_x - j phi_y (eq. 5)
                const cd step = divide(f - wt[i], fp);
                z[i] -= step;
                const double s = std::abs(step);
                worst = (s > worst || std::isnan(s)) ? s : worst;
                if (std::abs(u[i]) <= a) idx.push_back(static_cast<int>(i));  // eq. 6 as printed
            }
            const bool noisy = p.sigma > 0.0 && !idx.empty();
            if (noisy) kick(z, u, idx, p.sigma, pool, g);
            if (!noisy && worst < kNewtonTol) break;
        }
        iterations = it + 1;
        guard(pool);
    }

    void guard(NormalPool& pool) {
        const size_t m = z.size();
        const double a = p.a_p, a2 = a * a, inner = a * (1.0 - 1e-6);
        idx.clear();
        for (size_t i = 0; i < m; ++i)
            if (!finite(z[i])) {
                z[i] = z_start[i];
                u[i] = z[i] - p.z_f;
                idx.push_back(static_cast<int>(i));
            }
        if (!idx.empty()) kick(z, u, idx, p.sigma, pool, g);
        for (size_t i = 0; i < m; ++i) {
            const cd ui = z[i] - p.z_f;
            if (!(std::abs(ui) < inner)) continue;
            const cd mirror = p.z_f + divide(a2, ui);             // keeps (phi, psi) exactly
            const cd radial = p.z_f + divide(a2, std::conj(ui));  // keeps the side
            z[i] = std::abs(mirror - z_start[i]) <= std::abs(radial - z_start[i]) ? mirror : radial;
        }
    }

    // Algorithm 1 lines 13-22: one guidance tick.
    void step(NormalPool& pool) {
        const size_t m = z.size();
        z_prev = z;
        used = dphi;
        for (int k = 0; k < p.K; ++k) {
            used = dphi;
            for (size_t i = 0; i < m; ++i) {
                wt[i] = cd(w[i].real() + used, w[i].imag());  // line 16: psi unchanged
                z[i] = z_prev[i];
            }
            calc_xy(pool);                                     // line 17
            double speed = 0.0;
            for (size_t i = 0; i < m; ++i) {
                dz[i] = z[i] - z_prev[i];
                speed = std::max(speed, std::abs(dz[i]));
            }
            const double v_max = speed / p.dT;                 // line 19
            if (v_max > 0.0) dphi = used * p.v_des / v_max;    // line 20
        }
        const cd rot_dt = p.rot / p.dT;
        for (size_t i = 0; i < m; ++i) {
            w[i] += used;
            pos[i] = z[i] * p.rot + p.origin;
            vel[i] = dz[i] * rot_dt;
        }
    }
};

struct Reader {
    std::ifstream in;
    explicit Reader(const char* path) : in(path) {
        if (!in) { std::fprintf(stderr, "cem_reference: cannot read %s\n", path); std::exit(2); }
    }
    double num() { double x; if (!(in >> x)) { std::fprintf(stderr, "cem_reference: short input\n"); std::exit(2); } return x; }
    cd cplx() { const double re = num(); return {re, num()}; }
};

// Problem header: m, a_p, sigma, v_des, dT, K, n, z_f, rot, origin, z0[m], w0[m], P, pool[P].
Params read_problem(Reader& r, std::vector<cd>& z0, std::vector<cd>& w0, NormalPool& pool) {
    Params p;
    const int m = static_cast<int>(r.num());
    p.a_p = r.num(); p.sigma = r.num(); p.v_des = r.num(); p.dT = r.num();
    p.K = static_cast<int>(r.num()); p.n = static_cast<int>(r.num());
    p.z_f = r.cplx(); p.rot = r.cplx(); p.origin = r.cplx();
    z0.resize(m); w0.resize(m);
    for (auto& v : z0) v = r.cplx();
    for (auto& v : w0) v = r.cplx();
    pool.values.resize(static_cast<size_t>(r.num()));
    for (auto& v : pool.values) v = r.num();
    return p;
}

int time_loop(const char* path, int ticks, int repeats) {
    Reader r(path);
    std::vector<cd> z0, w0;
    NormalPool pool;
    const Params p = read_problem(r, z0, w0, pool);
    std::vector<double> per_step, cpu_per_step;
    double checksum = 0.0;
    long iterations = 0;
    for (int rep = 0; rep < repeats; ++rep) {
        Navigator nav(p, z0, w0);
        pool.next = 0;
        double sum = 0.0;
        timespec c0{}, c1{};  // thread CPU time: on a shared core, time spent descheduled is not ours
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
        const auto t0 = std::chrono::steady_clock::now();
        for (int t = 0; t < ticks; ++t) {
            nav.step(pool);
            for (size_t i = 0; i < nav.pos.size(); ++i)  // consume the commands (sendCommands)
                sum += nav.pos[i].real() + nav.pos[i].imag() + nav.vel[i].real() + nav.vel[i].imag();
            iterations += nav.iterations;
        }
        const auto t1 = std::chrono::steady_clock::now();
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
        per_step.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / ticks);
        cpu_per_step.push_back(((c1.tv_sec - c0.tv_sec) * 1e9 + (c1.tv_nsec - c0.tv_nsec)) / ticks);
        checksum = sum;
    }
    std::sort(per_step.begin(), per_step.end());
    std::sort(cpu_per_step.begin(), cpu_per_step.end());
    std::printf("ns_per_step %.3f cpu_ns_per_step %.3f repeats %d ticks %d checksum %.17g\n",
                per_step[per_step.size() / 2], cpu_per_step[cpu_per_step.size() / 2], repeats, ticks, checksum);
    return 0;
}

// Check input: the problem header, then T and per tick: z_prev[m], w[m], dphi, P, pool[P].
// Prints per tick: z[m] (flow frame), vel[m] (world), dphi after the tick, normals drawn.
int check(const char* path) {
    Reader r(path);
    std::vector<cd> z0, w0;
    NormalPool unused;
    const Params p = read_problem(r, z0, w0, unused);
    const int ticks = static_cast<int>(r.num());
    const size_t m = z0.size();
    for (int t = 0; t < ticks; ++t) {
        Navigator nav(p, z0, w0);
        for (auto& v : nav.z) v = r.cplx();
        for (auto& v : nav.w) v = r.cplx();
        nav.dphi = r.num();
        NormalPool pool;
        pool.values.resize(static_cast<size_t>(r.num()));
        for (auto& v : pool.values) v = r.num();
        nav.step(pool);
        for (size_t i = 0; i < m; ++i) std::printf("%.17g %.17g ", nav.z[i].real(), nav.z[i].imag());
        for (size_t i = 0; i < m; ++i) std::printf("%.17g %.17g ", nav.vel[i].real(), nav.vel[i].imag());
        std::printf("%.17g %zu\n", nav.dphi, pool.next);
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "time" && argc == 5) return time_loop(argv[2], std::atoi(argv[3]), std::atoi(argv[4]));
    if (mode == "check" && argc == 3) return check(argv[2]);
    std::fprintf(stderr, "usage: cem_reference time INPUT TICKS REPEATS | check INPUT\n");
    return 2;
}

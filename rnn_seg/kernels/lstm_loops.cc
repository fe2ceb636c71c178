// The peephole LSTM's two loops over time as TensorFlow ops (rnn_seg/kernels/__init__.py).
//
// MtrnnLstmForward runs rnn_seg.lstm._forward_loop's steps and MtrnnLstmBackward
// rnn_seg.lstm._backward_loop's (the per-step factors of the chain rule included), with the
// same equations and operands: each step's recurrent product streams the weights once from a
// copy laid out per call in panels (no per-step packing), and the gate nonlinearities of the
// units a panel produces run right after it, on Eigen's vectorised tanh and logistic (those
// TensorFlow's own tanh and sigmoid use). Shapes: time-major, T steps, B rows, H units; gate
// order (g, i, f, o) as in rnn_seg.lstm.
//
// Panels cover one vector of units each: 16 where the library is built for AVX-512 (32 registers
// of 16 floats), 8 elsewhere (AVX2: 16 registers of 8 floats). Forward, panel p holds, for every
// k < H, the 4 gates' weights W[k, q H + L p + l] (q the gate, l < L lanes): one step of the
// product for L units is H broadcast-multiply-adds of 4 vectors. With AVX-512 one pass over the
// panel sums all 4 gates of up to 6 rows (24 accumulators); with AVX2 two passes sum 2 gates
// each (12 accumulators, 2 weight vectors and a broadcast fill 15 of the 16 registers), the
// panel stored pass by pass so that each pass streams its own weights once; every lane sums over
// k in the same order on both, so the two builds' forward products agree bit for bit. Backward,
// the product dz W^T (K = 4H): with AVX-512 the panel streams W[L p + l, 4 k + q] for q < 4 as
// four vectors, summed into four partial sums per row and added at the end; with AVX2 each unit's
// row of W is dotted with the rows of dz, two units at a time, a vector of k at a time (their
// lanes added at the end), which needs no broadcasts: in float32 the two builds' backward
// products agree to rounding (a relative 2e-7 on the tests' inputs). With bfloat16 weights (AVX512_BF16 only) a panel holds
// pairs of consecutive k for the dot product vdpbf16ps, the row operand is rounded to bfloat16
// (nearest even) and the float32 sum is rounded to bfloat16 and widened, as TensorFlow's
// bfloat16 matmul and cast do in rnn_seg.lstm.product.
//
// Threads: up to the op's intra-op thread count (at least 64 units a thread) share each step's
// panels, each claiming 32 units at a time of its own contiguous part of them first, then of the
// others' parts that are left (SharedSteps); a step starts once every panel of the one before is
// done (every unit's h_t, or every gate's dz_t, is read by the next step's product).
#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#if defined(__AVX512BF16__)
#include <immintrin.h>
#endif

#include "Eigen/Core"
#include "tensorflow/core/framework/op.h"
#include "tensorflow/core/framework/op_kernel.h"
#include "tensorflow/core/framework/shape_inference.h"
#include "tensorflow/core/util/work_sharder.h"

namespace {

using tensorflow::bfloat16;
using tensorflow::OpKernel;
using tensorflow::OpKernelConstruction;
using tensorflow::OpKernelContext;
using tensorflow::Tensor;
using tensorflow::TensorShape;
using tensorflow::errors::InvalidArgument;

#if defined(__AVX512F__)
constexpr int kLanes = 16;          // floats in a vector, units in a panel
constexpr int kForwardGates = 4;    // gates a forward pass over a panel sums
#else
constexpr int kLanes = 8;           // AVX2 (and any other target): 256-bit vectors
constexpr int kForwardGates = 2;
#endif
constexpr int kMaxRows = 6;         // batch rows a call of a product sums
constexpr int kChunkUnits = 32;     // units a thread claims at a time
constexpr int kUnitsPerThread = 64; // at least, for one more thread to share a step

typedef float vec __attribute__((vector_size(kLanes * sizeof(float))));
typedef Eigen::Array<float, kLanes, 1> Lanes;

// Keeps v in a vector register, so that the multiply-adds reading it do not each fold in a load
// of it. Without AVX (the generic build) a vec spans two registers and the constraint cannot be
// met: there it does nothing.
__attribute__((always_inline)) inline void in_register(vec& v) {
#if defined(__AVX__)
  asm("" : "+v"(v));
#else
  (void)v;
#endif
}

struct AlignedFree {
  void operator()(void* p) const { std::free(p); }
};

template <typename T>
std::unique_ptr<T[], AlignedFree> aligned_zeros(size_t count) {
  size_t bytes = (count * sizeof(T) + 63) / 64 * 64;
  T* p = static_cast<T*>(std::aligned_alloc(64, bytes));
  std::memset(p, 0, bytes);
  return std::unique_ptr<T[], AlignedFree>(p);
}

// A loop over steps whose panels several threads share. The panels are split into one
// contiguous part per participant; each participant claims chunks of its own part first, then
// of the others' that are left, and a step's panels are claimed only once every panel of the
// step before is done. A participant so streams the same weights on every step, which stay in
// its core's own caches where a core has caches of its own (two cores of separate L3 slices:
// each streams half of the weights from its L3 instead of all of them from memory). A
// participant that is descheduled (a busy machine) holds up a step by at most the chunk it
// claimed: the others claim the rest of its part, so the op never waits for a thread that has
// not started. Waiting spins for about a step's time, then sleeps until the step completes.
class SharedSteps {
 public:
  SharedSteps(int steps, int panels, int chunk, int parts)
      : steps_(steps), panels_(panels), chunk_(chunk),
        parts_(std::max(1, std::min(parts, panels))), claimed_(new Counter[parts_]) {}

  // Runs work(step, first_panel, end_panel) on chunks until every step is claimed;
  // start(step) runs before this participant's first chunk of a step.
  template <typename Start, typename Work>
  void participate(Start start, Work work) {
    const int home = homes_.fetch_add(1) % parts_;
    int64_t started = -1;
    for (int64_t step = 0;; ++step) {
      step = std::max(step, done_.load() / panels_);     // a late participant joins the present
      if (step >= steps_) return;
      wait_done(step * panels_);                         // the step before is complete
      for (int k = 0; k < parts_; ++k) {
        int first, end;
        while (claim((home + k) % parts_, step, &first, &end)) {
          if (started != step) {
            start(static_cast<int>(step));
            started = step;
          }
          work(static_cast<int>(step), first, end);
          const int64_t done = done_.fetch_add(end - first) + (end - first);
          if (done % panels_ == 0 && sleepers_.load() > 0) {
            { std::lock_guard<std::mutex> lock(mutex_); }
            wake_.notify_all();
          }
        }
      }
    }
  }

  // Until every panel of every step is done.
  void wait_all() { wait_done(int64_t(steps_) * panels_); }

  // A pool task enters before it participates (false: the op is over, return at once) and
  // leaves after; finish() (the op's own thread, after wait_all) waits for those inside.
  bool enter() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (finished_) return false;
    ++inside_;
    return true;
  }
  void leave() {
    { std::lock_guard<std::mutex> lock(mutex_); --inside_; }
    wake_.notify_all();
  }
  void finish() {
    std::unique_lock<std::mutex> lock(mutex_);
    finished_ = true;
    wake_.wait(lock, [&] { return inside_ == 0; });
  }

 private:
  // Part p: panels [p * panels / parts, (p + 1) * panels / parts); its counter counts the
  // panels of it claimed over all steps, one cache line a part.
  struct alignas(64) Counter {
    std::atomic<int64_t> claimed{0};
  };

  // Claims up to a chunk of part p's panels of `step`: false when none is left. Odd steps visit
  // a part's panels last to first: the panels a step streamed last are still in the cache when
  // the next starts, where weights larger than the cache would otherwise be evicted before their
  // reuse on every step.
  bool claim(int p, int64_t step, int* first, int* end) {
    const int64_t begin = int64_t(p) * panels_ / parts_,
                  size = int64_t(p + 1) * panels_ / parts_ - begin, stop = (step + 1) * size;
    int64_t lo = claimed_[p].claimed.load(), hi;
    do {
      if (lo >= stop) return false;
      hi = std::min(lo + chunk_, stop);
    } while (!claimed_[p].claimed.compare_exchange_weak(lo, hi));
    lo -= step * size;
    hi -= step * size;
    if (step % 2) {
      const int64_t mirrored = size - hi;
      hi = size - lo;
      lo = mirrored;
    }
    *first = static_cast<int>(begin + lo);
    *end = static_cast<int>(begin + hi);
    return true;
  }

  // Spins briefly (a step's panels usually complete within microseconds), then yields the
  // core while it waits, so that on a busy machine the thread it waits for runs instead of
  // a spin (sched_yield returns at once where nothing else wants the core), then sleeps.
  void wait_done(int64_t target) {
    for (int spins = 0; spins < kSpins; ++spins) {
      if (done_.load(std::memory_order_acquire) >= target) return;
#if defined(__x86_64__)
      __builtin_ia32_pause();
#endif
    }
    for (int yields = 0; yields < kYields; ++yields) {
      if (done_.load(std::memory_order_acquire) >= target) return;
      std::this_thread::yield();
    }
    std::unique_lock<std::mutex> lock(mutex_);
    sleepers_.fetch_add(1);
    wake_.wait(lock, [&] { return done_.load() >= target; });
    sleepers_.fetch_sub(1);
  }

  static constexpr int kSpins = 2000, kYields = 20000;
  const int64_t steps_, panels_, chunk_;
  const int parts_;
  std::unique_ptr<Counter[]> claimed_;
  std::atomic<int64_t> done_{0};
  std::atomic<int> homes_{0}, sleepers_{0};
  int inside_ = 0;
  bool finished_ = false;
  std::mutex mutex_;
  std::condition_variable wake_;
};

// Runs `participant(steps)` (which calls SharedSteps::participate with its own buffers) on the
// calling thread and on threads - 1 tasks of the op's intra-op pool (whose idle threads spin for
// work, so a task usually starts at once; threads of our own would compete with them for the
// cores). A task that starts after the op's steps are all done returns at once.
template <typename Participant>
void run_shared(OpKernelContext* ctx, int threads, int steps, int panels,
                Participant participant) {
  auto shared = std::make_shared<SharedSteps>(steps, panels, std::max(1, kChunkUnits / kLanes),
                                               threads);
  for (int t = 1; t < threads; ++t)
    ctx->device()->tensorflow_cpu_worker_threads()->workers->Schedule([shared, &participant] {
      if (!shared->enter()) return;
      participant(*shared);
      shared->leave();
    });
  participant(*shared);
  shared->wait_all();
  shared->finish();
}

int thread_count(OpKernelContext* ctx, int panels) {
  int pool = ctx->device()->tensorflow_cpu_worker_threads()->num_threads;
  return std::max(1, std::min(pool, panels * kLanes / kUnitsPerThread));
}

// ---- the products, float32 -------------------------------------------------------------------

// W_h laid out in panels for one of the two products (forward h W, backward dz W^T).
struct Fp32Panels {
  using Weight = float;
  int panels, depth;            // depth: steps of 4 vectors of kLanes floats per panel
  int group;                    // vectors a pass sums: kForwardGates forward, 4 backward
  std::unique_ptr<float[], AlignedFree> data;

  // forward: h W, W [H, 4H] row-major; the panel pass by pass (kForwardGates gates each)
  static Fp32Panels forward(const float* w, int hidden) {
    return packed(hidden, kForwardGates, [&](int k, int q, int unit) {
      return w[size_t(k) * 4 * hidden + q * hidden + unit];
    });
  }

#if defined(__AVX512F__)
  // backward: dz W^T, four consecutive k per step of the panel, in one pass
  static Fp32Panels backward(const float* w, int hidden) {
    return packed(hidden, 4, [&](int k, int q, int unit) {
      return w[size_t(unit) * 4 * hidden + 4 * k + q];
    });
  }
#else
  // backward: dz W^T as each unit's row of W (its 4H weights, zero-padded to whole vectors),
  // dotted with the rows of dz; zero rows past the units
  static Fp32Panels backward(const float* w, int hidden) {
    Fp32Panels p{(hidden + kLanes - 1) / kLanes, hidden, 4, nullptr};
    const size_t n = 4 * size_t(hidden);
    p.data = aligned_zeros<float>(size_t(p.panels) * kLanes * p.row_stride());
    for (int unit = 0; unit < hidden; ++unit)
      std::memcpy(p.unit_row(unit), w + unit * n, n * sizeof(float));
    return p;
  }

  size_t row_stride() const { return (4 * size_t(depth) + kLanes - 1) / kLanes * kLanes; }
  float* unit_row(int unit) const { return data.get() + unit * row_stride(); }
#endif

  // panel p, pass q / group, depth k, vector q % group, lane l <- weight(k, q, p L + l); zero
  // past the units
  template <class Weight>
  static Fp32Panels packed(int hidden, int group, Weight weight) {
    Fp32Panels p{(hidden + kLanes - 1) / kLanes, hidden, group, nullptr};
    p.data = aligned_zeros<float>(size_t(p.panels) * p.depth * 4 * kLanes);
    for (int panel = 0; panel < p.panels; ++panel)
      for (int k = 0; k < hidden; ++k)
        for (int q = 0; q < 4; ++q)
          for (int l = 0; l < kLanes; ++l) {
            int unit = panel * kLanes + l;
            if (unit < hidden)
              p.at(panel, q / group, k)[(q % group) * kLanes + l] = weight(k, q, unit);
          }
    return p;
  }

  float* at(int panel, int pass, int k) const {
    return data.get() + ((size_t(panel) * (4 / group) + pass) * depth + k) * group * kLanes;
  }

  // Row operand as the backward product reads it: the rows themselves.
  struct Rows {
    const float* base;
    size_t stride;
    void prepare(const float* rows, int, size_t row_stride, int) {
      base = rows;
      stride = row_stride;
    }
  };

  // Row operand as the forward product reads it: the rows k-major in groups of kMaxRows (zeros
  // past the last row), so that a step of k broadcasts from one pointer at fixed offsets. With a
  // pointer per row the compiler kept them on the stack (16 general registers), and a step of k
  // loaded them again: 13 loads for 12 multiply-adds with AVX2, at half the multiply-adds' rate.
  struct ForwardRows {
    std::vector<float> packed;
    int depth = 0;
    void prepare(const float* rows, int count, size_t row_stride, int length) {
      depth = length;
      packed.assign(size_t((count + kMaxRows - 1) / kMaxRows) * length * kMaxRows, 0.0f);
      for (int b = 0; b < count; ++b) {
        float* to = packed.data() + size_t(b / kMaxRows) * length * kMaxRows + b % kMaxRows;
        const float* from = rows + b * row_stride;
        for (int k = 0; k < length; ++k) to[k * kMaxRows] = from[k];
      }
    }
    // The group of rows row0.. (row0 a multiple of kMaxRows).
    const float* group(int row0) const {
      return packed.data() + size_t(row0 / kMaxRows) * depth * kMaxRows;
    }
  };

  // out[r][0..3]: forward, the 4 gates' sums for the panel's units; backward, the sum over the
  // panel's 4 vectors in out[r][0].
  template <int R, bool kBackward, typename RowsT>
  void product(const RowsT& rows, int row0, int panel, vec (*acc_out)[4]) const {
    if constexpr (kBackward) {
      backward_sums<R>(rows, row0, panel, acc_out);
    } else {
      for (int pass = 0; pass < 4 / kForwardGates; ++pass)
        forward_pass<R>(rows, row0, panel, pass, acc_out);
    }
  }

  // The sums stay in registers: written through acc_out every step, they would be stored after
  // each multiply-add (acc_out may alias the rows, so the compiler keeps memory up to date),
  // which halved the product's rate.
  template <int R>
  void forward_pass(const ForwardRows& rows, int row0, int panel, int pass,
                    vec (*acc_out)[4]) const {
    vec acc[R][kForwardGates];
    for (int r = 0; r < R; ++r)
      for (int q = 0; q < kForwardGates; ++q) acc[r][q] = vec{};
    const float* a = rows.group(row0);
    const vec* w = reinterpret_cast<const vec*>(at(panel, pass, 0));
    for (int k = 0; k < depth; ++k, w += kForwardGates, a += kMaxRows) {
      vec wq[kForwardGates];
      for (int q = 0; q < kForwardGates; ++q) {
        // folded into every multiply-add as a memory operand, the weights were loaded once per
        // row (13 loads for 12 multiply-adds with AVX2)
        vec v = w[q];
        in_register(v);
        wq[q] = v;
      }
      for (int r = 0; r < R; ++r) {
        const float s = a[r];
        for (int q = 0; q < kForwardGates; ++q) acc[r][q] += s * wq[q];
      }
    }
    for (int r = 0; r < R; ++r)
      for (int q = 0; q < kForwardGates; ++q) acc_out[r][pass * kForwardGates + q] = acc[r][q];
  }

#if defined(__AVX512F__)
  // The rows' four partial sums each, added at the end.
  template <int R>
  void backward_sums(const Rows& rows, int row0, int panel, vec (*acc_out)[4]) const {
    vec acc[R][4];
    for (int r = 0; r < R; ++r)
      for (int q = 0; q < 4; ++q) acc[r][q] = vec{};
    const float* a[R];
    for (int r = 0; r < R; ++r) a[r] = rows.base + (row0 + r) * rows.stride;
    const vec* w = reinterpret_cast<const vec*>(at(panel, 0, 0));
    for (int k = 0; k < depth; ++k, w += 4) {
      for (int r = 0; r < R; ++r) {
        const float* s = a[r] + 4 * k;
        for (int q = 0; q < 4; ++q) acc[r][q] += s[q] * w[q];
      }
    }
    for (int r = 0; r < R; ++r) acc_out[r][0] = (acc[r][0] + acc[r][1]) + (acc[r][2] + acc[r][3]);
  }
#else
  // Two units at a time, each unit's row of W against every row of dz, a vector of k at a time:
  // 2 R lane-wise sums (10 registers at most), added across their lanes at the end. No
  // broadcasts, which the partial sums above need four of per step of k and row, and which share
  // a port with the multiply-adds on AVX2 cores.
  typedef float unaligned_vec __attribute__((vector_size(kLanes * sizeof(float)), aligned(4)));
  // Rows a loop sums at most: 6 rows' 12 sums, 2 weight vectors and a row's vector would take
  // 15 of the 16 registers, and GCC 12 then kept 4 sums on the stack (bench/kernel_loops.py);
  // 6 rows are summed as 3 and 3.
  static constexpr int kBackwardRows = 5;

  template <int R>
  void backward_sums(const Rows& rows, int row0, int panel, vec (*acc_out)[4]) const {
    if constexpr (R > kBackwardRows) {
      backward_sums<R / 2>(rows, row0, panel, acc_out);
      backward_sums<R - R / 2>(rows, row0 + R / 2, panel, acc_out + R / 2);
    } else {
      backward_rows<R>(rows, row0, panel, acc_out);
    }
  }

  template <int R>
  void backward_rows(const Rows& rows, int row0, int panel, vec (*acc_out)[4]) const {
    const int n = 4 * depth, whole = n / kLanes;
    const float* a[R];
    for (int r = 0; r < R; ++r) a[r] = rows.base + (row0 + r) * rows.stride;
    for (int l = 0; l < kLanes; l += 2) {
      const float* w0 = unit_row(panel * kLanes + l);
      const float* w1 = w0 + row_stride();
      vec acc[R][2];
      for (int r = 0; r < R; ++r) acc[r][0] = acc[r][1] = vec{};
      for (int k = 0; k < whole; ++k) {
        const vec x0 = reinterpret_cast<const vec*>(w0)[k], x1 = reinterpret_cast<const vec*>(w1)[k];
        for (int r = 0; r < R; ++r) {
          vec d = reinterpret_cast<const unaligned_vec*>(a[r])[k];
          in_register(d);         // folded into both multiply-adds, it was loaded twice
          acc[r][0] += d * x0;
          acc[r][1] += d * x1;
        }
      }
      for (int r = 0; r < R; ++r) {
        float s0 = across(acc[r][0]), s1 = across(acc[r][1]);
        for (int k = whole * kLanes; k < n; ++k) {        // 4H not a whole number of vectors
          s0 += a[r][k] * w0[k];
          s1 += a[r][k] * w1[k];
        }
        acc_out[r][0][l] = s0;
        acc_out[r][0][l + 1] = s1;
      }
    }
  }

  // The sum of a vector's lanes, pairwise.
  static float across(vec v) {
    for (int width = kLanes / 2; width > 0; width /= 2)
      for (int l = 0; l < width; ++l) v[l] += v[l + width];
    return v[0];
  }
#endif
};

// ---- the products, bfloat16 (AVX512_BF16) ----------------------------------------------------

#if defined(__AVX512BF16__)
uint16_t bits(bfloat16 x) {
  uint16_t b;
  std::memcpy(&b, &x, 2);
  return b;
}

struct Bf16Panels {
  using Weight = bfloat16;
  int panels, depth;                       // depth: steps of 4 vectors of 16 bfloat16 pairs
  std::unique_ptr<uint16_t[], AlignedFree> data;

  uint16_t* at(int panel, int k2) const {
    return data.get() + (size_t(panel) * depth + k2) * 4 * kLanes * 2;
  }

  // forward: vector q at step k2 holds (W[2 k2, col], W[2 k2 + 1, col]), col = q H + unit
  static Bf16Panels forward(const bfloat16* w, int hidden) {
    Bf16Panels p{(hidden + kLanes - 1) / kLanes, (hidden + 1) / 2, nullptr};
    p.data = aligned_zeros<uint16_t>(size_t(p.panels) * p.depth * 4 * kLanes * 2);
    for (int panel = 0; panel < p.panels; ++panel)
      for (int k = 0; k < hidden; ++k)
        for (int q = 0; q < 4; ++q)
          for (int l = 0; l < kLanes; ++l) {
            int unit = panel * kLanes + l;
            if (unit < hidden)
              p.at(panel, k / 2)[(q * kLanes + l) * 2 + k % 2] =
                  bits(w[size_t(k) * 4 * hidden + q * hidden + unit]);
          }
    return p;
  }

  // backward: vector q at step k2 holds (W[unit, 8 k2 + 2 q], W[unit, 8 k2 + 2 q + 1])
  static Bf16Panels backward(const bfloat16* w, int hidden) {
    Bf16Panels p{(hidden + kLanes - 1) / kLanes, (hidden + 1) / 2, nullptr};
    p.data = aligned_zeros<uint16_t>(size_t(p.panels) * p.depth * 4 * kLanes * 2);
    for (int panel = 0; panel < p.panels; ++panel)
      for (int k = 0; k < 4 * hidden; ++k)
        for (int l = 0; l < kLanes; ++l) {
          int unit = panel * kLanes + l;
          if (unit < hidden)
            p.at(panel, k / 8)[((k % 8) / 2 * kLanes + l) * 2 + k % 2] =
                bits(w[size_t(unit) * 4 * hidden + k]);
        }
    return p;
  }

  // Row operand: every row rounded to bfloat16 (nearest even), in pairs, padded with zeros.
  struct Rows;
  using ForwardRows = Rows;
  struct Rows {
    std::vector<uint32_t> pairs;
    size_t stride = 0;
    void prepare(const float* rows, int count, size_t row_stride, int length) {
      stride = (length + 31) / 32 * 16;       // pairs, whole vectors of 16
      pairs.assign(count * stride, 0);
      std::vector<float> padded(stride * 2);
      for (int r = 0; r < count; ++r) {
        std::fill(padded.begin(), padded.end(), 0.0f);
        std::copy(rows + r * row_stride, rows + r * row_stride + length, padded.begin());
        for (size_t k = 0; k < stride * 2; k += 32) {
          __m512 lo = _mm512_loadu_ps(&padded[k]), hi = _mm512_loadu_ps(&padded[k + 16]);
          __m512bh b = _mm512_cvtne2ps_pbh(hi, lo);
          _mm512_storeu_si512(&pairs[r * stride + k / 2], (__m512i)b);
        }
      }
    }
  };

  // Without SLP vectorization: GCC's SLP vectorizer grouped the four consecutive pairs a
  // backward row loads per step of k into one vector and then stored every sum to the stack each
  // step (24 stores for 24 dot products at 6 rows; bench/kernel_loops.py lists them).
  template <int R, bool kBackward>
  __attribute__((optimize("no-tree-slp-vectorize")))
  void product(const Rows& rows, int row0, int panel, vec (*acc_out)[4]) const {
    __m512 acc[R][4];
    for (int r = 0; r < R; ++r)
      for (int q = 0; q < 4; ++q) acc[r][q] = _mm512_setzero_ps();
    const uint32_t* a[R];
    for (int r = 0; r < R; ++r) a[r] = rows.pairs.data() + (row0 + r) * rows.stride;
    const uint16_t* w = at(panel, 0);
    for (int k = 0; k < depth; ++k, w += 4 * kLanes * 2) {
      __m512bh wq[4];
      for (int q = 0; q < 4; ++q)
        wq[q] = (__m512bh)_mm512_load_si512(reinterpret_cast<const void*>(w + q * kLanes * 2));
      for (int r = 0; r < R; ++r)
        for (int q = 0; q < 4; ++q) {
          uint32_t s = kBackward ? a[r][4 * k + q] : a[r][k];
          acc[r][q] = _mm512_dpbf16_ps(acc[r][q], (__m512bh)_mm512_set1_epi32(s), wq[q]);
        }
    }
    for (int r = 0; r < R; ++r) {
      if (kBackward)
        acc[r][0] = _mm512_add_ps(_mm512_add_ps(acc[r][0], acc[r][1]),
                                  _mm512_add_ps(acc[r][2], acc[r][3]));
      for (int q = 0; q < (kBackward ? 1 : 4); ++q) {   // the product's bfloat16 result
        __m256bh rounded = _mm512_cvtneps_pbh(acc[r][q]);
        __m512i widened = _mm512_slli_epi32(_mm512_cvtepu16_epi32((__m256i)rounded), 16);
        acc_out[r][q] = (vec)_mm512_castsi512_ps(widened);
      }
    }
  }
};
#endif

template <typename Panels, bool kBackward, typename RowsT>
void product_rows(const Panels& w, const RowsT& rows, int row0, int count,
                  int panel, vec (*acc)[4]) {
  switch (count) {
    case 1: w.template product<1, kBackward>(rows, row0, panel, acc); break;
    case 2: w.template product<2, kBackward>(rows, row0, panel, acc); break;
    case 3: w.template product<3, kBackward>(rows, row0, panel, acc); break;
    case 4: w.template product<4, kBackward>(rows, row0, panel, acc); break;
    case 5: w.template product<5, kBackward>(rows, row0, panel, acc); break;
    default: w.template product<6, kBackward>(rows, row0, panel, acc); break;
  }
}

// kLanes lanes of a [.., H] row from `unit` on (zeros past H), and back.
// Inlined: a call each (the compiler's choice in the backward op) took 8 % of its time.
__attribute__((always_inline)) inline Lanes load(const float* row, int unit, int hidden) {
  if (unit + kLanes <= hidden) return Eigen::Map<const Lanes>(row + unit);
  Lanes v;
  v.setZero();
  for (int l = 0; l < kLanes && unit + l < hidden; ++l) v[l] = row[unit + l];
  return v;
}

__attribute__((always_inline)) inline void store(const Lanes& v, float* row, int unit,
                                                 int hidden) {
  if (unit + kLanes <= hidden) {
    Eigen::Map<Lanes>(row + unit) = v;
    return;
  }
  for (int l = 0; l < kLanes && unit + l < hidden; ++l) row[unit + l] = v[l];
}

// A vector of a [.., H] row from `unit` on (zeros past H) as the products' type, in registers:
// as an Eigen array, the gate inputs went through memory in 16-byte halves (GCC splits an
// unaligned 256-bit store for AMD's and generic tuning) that a whole vector then waited for,
// 15 % of the forward op's time at 256 units on the AVX2 EPYC.
vec gate_inputs(const float* row, int unit, int hidden) {
  vec v;
  if (unit + kLanes <= hidden) {
    std::memcpy(&v, row + unit, sizeof(v));            // one unaligned vector load
    return v;
  }
  v = vec{};
  std::memcpy(&v, row + unit, sizeof(float) * std::max(0, hidden - unit));
  return v;
}

Lanes lanes(const vec& v) {
  return Eigen::Map<const Lanes, Eigen::AlignedMax>(reinterpret_cast<const float*>(&v));
}

// ---- forward ---------------------------------------------------------------------------------

struct Dims {
  int steps, size, batch, hidden;
};

template <typename Panels>
void forward(OpKernelContext* ctx, const Dims& d, const float* x_proj, const float* keep,
             const typename Panels::Weight* w_h, const float* peep, float* out[6]) {
  const int H = d.hidden, B = d.batch;
  const Panels w = Panels::forward(w_h, H);
  const size_t step = size_t(B) * H;
  float *h = out[0], *c = out[1], *g = out[2], *i = out[3], *f = out[4], *o = out[5];
  run_shared(ctx, thread_count(ctx, w.panels), d.steps, w.panels, [&](SharedSteps& steps) {
    typename Panels::ForwardRows rows;
    vec acc[kMaxRows][4];
    auto start = [&](int t) {                            // every unit's h_{t-1} is written
      if (t > 0) rows.prepare(h + (t - 1) * step, B, H, H);
    };
    steps.participate(start, [&](int t, int first, int end) {
      for (int panel = first; panel < end; ++panel) {
        const int unit = panel * kLanes;
        const Lanes w_ic = load(peep, unit, H), w_fc = load(peep + H, unit, H),
                    w_oc = load(peep + 2 * H, unit, H);
        for (int row0 = 0; row0 < B; row0 += kMaxRows) {
          const int count = std::min(kMaxRows, B - row0);
          if (t > 0) product_rows<Panels, false>(w, rows, row0, count, panel, acc);
          for (int r = 0; r < count; ++r) {
            const int b = row0 + r;
            const float k = keep[t * B + b];
            const float* z_x = x_proj + (size_t(t) * B + b) * 4 * H;
            vec z[4];                   // in registers (gate_inputs)
            for (int q = 0; q < 4; ++q) {
              z[q] = gate_inputs(z_x + q * H, unit, H);
              if (t > 0) z[q] += acc[r][q] * k;
            }
            Lanes c_prev = Lanes::Zero();
            if (t > 0) c_prev = load(c + (t - 1) * step + b * H, unit, H) * k;
            const Lanes g_t = lanes(z[0]).tanh();
            const Lanes i_t = (lanes(z[1]) + w_ic * c_prev).logistic();
            const Lanes f_t = (lanes(z[2]) + w_fc * c_prev).logistic();
            const Lanes c_t = g_t * i_t + c_prev * f_t;
            const Lanes o_t = (lanes(z[3]) + w_oc * c_t).logistic();
            const Lanes h_t = o_t * c_t.tanh();
            const size_t at = t * step + b * H;
            store(h_t, h + at, unit, H);
            store(c_t, c + at, unit, H);
            store(g_t, g + at, unit, H);
            store(i_t, i + at, unit, H);
            store(f_t, f + at, unit, H);
            store(o_t, o + at, unit, H);
          }
        }
      }
    });
  });
}

// ---- backward --------------------------------------------------------------------------------

template <typename Panels>
void backward(OpKernelContext* ctx, const Dims& d, const float* dh_out, const float* keep,
              const float* state[5], const float* c_prev, const typename Panels::Weight* w_h,
              const float* peep, float* dz) {
  const int H = d.hidden, B = d.batch;
  const Panels w = Panels::backward(w_h, H);
  const size_t step = size_t(B) * H;
  const float *c = state[0], *g = state[1], *i = state[2], *f = state[3], *o = state[4];
  std::vector<float> dh_next(step, 0.0f), dc_next(step, 0.0f);   // reaching step t from t + 1
  // Shared step s runs time t = steps - 1 - s for a panel's units: the product dz_{t+1} W^T
  // (every unit's dz_{t+1} is written) gives their dh reaching t, then their dz_t.
  run_shared(ctx, thread_count(ctx, w.panels), d.steps, w.panels, [&](SharedSteps& steps) {
    typename Panels::Rows rows;
    vec acc[kMaxRows][4];
    auto start = [&](int s) {
      const int t = d.steps - 1 - s;
      if (s > 0) rows.prepare(dz + size_t(t + 1) * B * 4 * H, B, 4 * H, 4 * H);
    };
    steps.participate(start, [&](int s, int first, int end) {
      const int t = d.steps - 1 - s;
      for (int panel = first; panel < end; ++panel) {
        const int unit = panel * kLanes;
        for (int row0 = 0; s > 0 && row0 < B; row0 += kMaxRows) {    // dh reaching step t
          const int count = std::min(kMaxRows, B - row0);
          product_rows<Panels, true>(w, rows, row0, count, panel, acc);
          for (int r = 0; r < count; ++r) {
            const int b = row0 + r;
            store(lanes(acc[r][0]) * keep[(t + 1) * B + b], &dh_next[b * H], unit, H);
          }
        }
        const Lanes w_ic = load(peep, unit, H), w_fc = load(peep + H, unit, H),
                    w_oc = load(peep + 2 * H, unit, H);
        for (int b = 0; b < B; ++b) {                                // dz_t of these units
          const size_t at = t * step + b * H;
          const Lanes c_t = load(c + at, unit, H), g_t = load(g + at, unit, H),
                      i_t = load(i + at, unit, H), f_t = load(f + at, unit, H),
                      o_t = load(o + at, unit, H), cp = load(c_prev + at, unit, H);
          const Lanes tc = c_t.tanh();
          const Lanes d_i = i_t * (1.0f - i_t), d_f = f_t * (1.0f - f_t);
          const Lanes out_o = tc * o_t * (1.0f - o_t);
          const Lanes out_c = o_t * (1.0f - tc * tc) + out_o * w_oc;
          const Lanes to_prev = keep[t * B + b] * (f_t + g_t * d_i * w_ic + cp * d_f * w_fc);
          const Lanes dh = load(dh_out + at, unit, H) + load(&dh_next[b * H], unit, H);
          const Lanes dc = load(&dc_next[b * H], unit, H) + dh * out_c;
          float* dz_t = dz + (size_t(t) * B + b) * 4 * H;
          store(dc * (i_t * (1.0f - g_t * g_t)), dz_t, unit, H);
          store(dc * (g_t * d_i), dz_t + H, unit, H);
          store(dc * (cp * d_f), dz_t + 2 * H, unit, H);
          store(dh * out_o, dz_t + 3 * H, unit, H);
          store(dc * to_prev, &dc_next[b * H], unit, H);
        }
      }
    });
  });
}

// ---- the ops ---------------------------------------------------------------------------------

tensorflow::Status check(const Tensor& x, int rank, const char* name) {
  if (x.dims() != rank)
    return InvalidArgument(name, " must have rank ", rank, ", got ", x.shape().DebugString());
  return tensorflow::OkStatus();
}

// ---- the recurrent weights' gradient, float32 ------------------------------------------------

// dW_h = h_prev^T dz over all steps and rows: A [N, M] (h entering each step, N = T B rows, M = H
// units) and B [N, Q] (dz, Q = 4H) give C = A^T B [M, Q]. Where TensorFlow's own matmul runs
// Eigen's contraction (a build without AVX2 and FMA in its general code), it sums at about half the
// rate of this kernel's multiply-adds (docs/PERFORMANCE.md). Blocked as BLIS does: k in blocks
// of kGradDepth, B's block packed in panels of kGradCols columns (k-major), A's block packed in
// micro-panels of kGradRows rows (k-major; rows past M hold any values and are never written
// back), and a micro-kernel that keeps a kGradRows x kGradCols block of C in 12 registers. Each
// element of C sums each block's k in order, then adds the blocks' sums in order: the same bits
// on any number of threads.
constexpr int kGradRows = 6;
constexpr int kGradCols = 2 * kLanes;
constexpr int kGradDepth = 256;
constexpr int kGradRowBlock = 16 * kGradRows;      // rows of A packed at a time (L2)

// c[r * ldc + j] (+)= sum over k of a[k * kGradRows + r] * b[k * kGradCols + j], for r < rows,
// j < cols; `add` false: the first block, which stores.
inline void weight_gradient_block(int depth, const float* a, const float* b, float* c,
                                  size_t ldc, int rows, int cols, bool add) {
  vec acc[kGradRows][2];
  for (int r = 0; r < kGradRows; ++r) acc[r][0] = acc[r][1] = vec{};
  const vec* bv = reinterpret_cast<const vec*>(b);
  for (int k = 0; k < depth; ++k, a += kGradRows, bv += 2) {
    const vec b0 = bv[0], b1 = bv[1];
    for (int r = 0; r < kGradRows; ++r) {
      acc[r][0] += a[r] * b0;
      acc[r][1] += a[r] * b1;
    }
  }
  for (int r = 0; r < rows; ++r) {
    float* out = c + r * ldc;
    const float* sums = reinterpret_cast<const float*>(acc[r]);
    if (add)
      for (int j = 0; j < cols; ++j) out[j] += sums[j];
    else
      std::memcpy(out, sums, cols * sizeof(float));
  }
}

// Columns [col0, col1) of C (col0 a multiple of kGradCols).
void weight_gradient_columns(const float* a, const float* b, float* c, int64_t n, int m, int q,
                             int col0, int col1) {
  const int panels = (col1 - col0 + kGradCols - 1) / kGradCols;
  const int row_panels = (std::min(m, kGradRowBlock) + kGradRows - 1) / kGradRows;
  auto packed_b = aligned_zeros<float>(size_t(panels) * kGradDepth * kGradCols);
  auto packed_a = aligned_zeros<float>(size_t(row_panels) * kGradDepth * kGradRows);
  for (int64_t k0 = 0; k0 < n; k0 += kGradDepth) {
    const int depth = int(std::min<int64_t>(kGradDepth, n - k0));
    for (int p = 0; p < panels; ++p) {                  // B's block, panel by panel
      const int first = col0 + p * kGradCols, cols = std::min(kGradCols, col1 - first);
      float* to = packed_b.get() + size_t(p) * kGradDepth * kGradCols;
      for (int k = 0; k < depth; ++k)
        std::memcpy(to + k * kGradCols, b + (k0 + k) * q + first, cols * sizeof(float));
    }
    for (int row0 = 0; row0 < m; row0 += kGradRowBlock) {
      const int rows = std::min(kGradRowBlock, m - row0);
      for (int rp = 0; rp * kGradRows < rows; ++rp) {   // A's block, micro-panel by micro-panel
        float* to = packed_a.get() + size_t(rp) * kGradDepth * kGradRows;
        const int count = std::min(kGradRows, rows - rp * kGradRows);
        for (int k = 0; k < depth; ++k)
          std::memcpy(to + k * kGradRows, a + (k0 + k) * m + row0 + rp * kGradRows,
                      count * sizeof(float));
      }
      for (int p = 0; p < panels; ++p) {
        const int first = col0 + p * kGradCols, cols = std::min(kGradCols, col1 - first);
        for (int rp = 0; rp * kGradRows < rows; ++rp) {
          const int row = row0 + rp * kGradRows;
          weight_gradient_block(depth, packed_a.get() + size_t(rp) * kGradDepth * kGradRows,
                                packed_b.get() + size_t(p) * kGradDepth * kGradCols,
                                c + size_t(row) * q + first, q,
                                std::min(kGradRows, m - row), cols, k0 > 0);
        }
      }
    }
  }
}

class WeightGradientOp : public OpKernel {
 public:
  explicit WeightGradientOp(OpKernelConstruction* ctx) : OpKernel(ctx) {}

  void Compute(OpKernelContext* ctx) override {
    const Tensor &a = ctx->input(0), &b = ctx->input(1);
    OP_REQUIRES_OK(ctx, check(a, 2, "h_prev"));
    OP_REQUIRES_OK(ctx, check(b, 2, "dz"));
    OP_REQUIRES(ctx, a.dim_size(0) == b.dim_size(0),
                InvalidArgument("h_prev ", a.shape().DebugString(), " and dz ",
                                b.shape().DebugString(), " have other numbers of rows"));
    const int64_t n = a.dim_size(0);
    const int m = int(a.dim_size(1)), q = int(b.dim_size(1));
    Tensor* c = nullptr;
    OP_REQUIRES_OK(ctx, ctx->allocate_output(0, TensorShape({m, q}), &c));
    float* out = c->flat<float>().data();
    if (n == 0) {
      std::fill(out, out + c->NumElements(), 0.0f);
      return;
    }
    const float *pa = a.flat<float>().data(), *pb = b.flat<float>().data();
    const int panels = (q + kGradCols - 1) / kGradCols;
    auto* workers = ctx->device()->tensorflow_cpu_worker_threads();
    // Each shard a run of whole column panels; the cost of a panel: its multiply-adds.
    tensorflow::Shard(workers->num_threads, workers->workers, panels,
                      n * m * kGradCols, [&](int64_t first, int64_t end) {
                        weight_gradient_columns(pa, pb, out, n, m, q, int(first) * kGradCols,
                                                std::min<int>(q, int(end) * kGradCols));
                      });
  }
};

template <typename T>
class ForwardOp : public OpKernel {
 public:
  explicit ForwardOp(OpKernelConstruction* ctx) : OpKernel(ctx) {}

  void Compute(OpKernelContext* ctx) override {
    const Tensor &x_proj = ctx->input(0), &keep = ctx->input(1), &w = ctx->input(2),
                 &peep = ctx->input(3), &steps = ctx->input(4);
    OP_REQUIRES_OK(ctx, check(x_proj, 3, "x_proj"));
    OP_REQUIRES_OK(ctx, check(w, 2, "w"));
    OP_REQUIRES_OK(ctx, check(steps, 0, "steps"));
    const Dims d{steps.scalar<int32_t>()(), int(x_proj.dim_size(0)), int(x_proj.dim_size(1)),
                 int(w.dim_size(0))};
    OP_REQUIRES(ctx, d.hidden > 0, InvalidArgument("w must have at least one unit, got ",
                                                    w.shape().DebugString()));
    OP_REQUIRES(ctx, x_proj.dim_size(2) == 4 * d.hidden && w.dim_size(1) == 4 * d.hidden &&
                     peep.NumElements() == 3 * d.hidden && keep.NumElements() == d.size * d.batch,
                InvalidArgument("inconsistent shapes: x_proj ", x_proj.shape().DebugString(),
                                ", w ", w.shape().DebugString(), ", peep ",
                                peep.shape().DebugString(), ", keep ",
                                keep.shape().DebugString()));
    OP_REQUIRES(ctx, d.steps >= 0 && d.steps <= d.size,
                InvalidArgument("steps ", d.steps, " outside 0..", d.size));
    float* out[6];
    for (int k = 0; k < 6; ++k) {
      Tensor* t = nullptr;
      OP_REQUIRES_OK(ctx, ctx->allocate_output(k, TensorShape({d.size, d.batch, d.hidden}), &t));
      out[k] = t->flat<float>().data();
      std::fill(out[k] + size_t(d.steps) * d.batch * d.hidden, out[k] + t->NumElements(), 0.0f);
    }
    run(ctx, d, x_proj.flat<float>().data(), keep.flat<float>().data(), w.flat<T>().data(),
        peep.flat<float>().data(), out);
  }

 private:
  void run(OpKernelContext* ctx, const Dims& d, const float* x_proj, const float* keep,
           const T* w, const float* peep, float* out[6]);
};

template <>
void ForwardOp<float>::run(OpKernelContext* ctx, const Dims& d, const float* x_proj,
                           const float* keep, const float* w, const float* peep, float* out[6]) {
  forward<Fp32Panels>(ctx, d, x_proj, keep, w, peep, out);
}

template <typename T>
class BackwardOp : public OpKernel {
 public:
  explicit BackwardOp(OpKernelConstruction* ctx) : OpKernel(ctx) {}

  void Compute(OpKernelContext* ctx) override {
    const Tensor &dh_out = ctx->input(0), &keep = ctx->input(1), &c_prev = ctx->input(7),
                 &w = ctx->input(8), &peep = ctx->input(9), &steps = ctx->input(10);
    OP_REQUIRES_OK(ctx, check(dh_out, 3, "dh_out"));
    OP_REQUIRES_OK(ctx, check(w, 2, "w"));
    OP_REQUIRES_OK(ctx, check(steps, 0, "steps"));
    const Dims d{steps.scalar<int32_t>()(), int(dh_out.dim_size(0)), int(dh_out.dim_size(1)),
                 int(w.dim_size(0))};
    OP_REQUIRES(ctx, d.hidden > 0, InvalidArgument("w must have at least one unit, got ",
                                                    w.shape().DebugString()));
    OP_REQUIRES(ctx, dh_out.dim_size(2) == d.hidden && w.dim_size(1) == 4 * d.hidden &&
                     peep.NumElements() == 3 * d.hidden && keep.NumElements() == d.size * d.batch,
                InvalidArgument("inconsistent shapes: dh_out ", dh_out.shape().DebugString(),
                                ", w ", w.shape().DebugString()));
    const float* state[5];
    for (int k = 0; k < 5; ++k) {
      OP_REQUIRES(ctx, ctx->input(2 + k).shape() == dh_out.shape(),
                  InvalidArgument("state ", k, " has shape ",
                                  ctx->input(2 + k).shape().DebugString()));
      state[k] = ctx->input(2 + k).flat<float>().data();
    }
    OP_REQUIRES(ctx, c_prev.shape() == dh_out.shape(), InvalidArgument("c_prev's shape"));
    OP_REQUIRES(ctx, d.steps >= 0 && d.steps <= d.size,
                InvalidArgument("steps ", d.steps, " outside 0..", d.size));
    Tensor* dz = nullptr;
    OP_REQUIRES_OK(ctx, ctx->allocate_output(0, TensorShape({d.size, d.batch, 4 * d.hidden}),
                                             &dz));
    float* out = dz->flat<float>().data();
    std::fill(out + size_t(d.steps) * d.batch * 4 * d.hidden, out + dz->NumElements(), 0.0f);
    run(ctx, d, dh_out.flat<float>().data(), keep.flat<float>().data(), state,
        c_prev.flat<float>().data(), w.flat<T>().data(), peep.flat<float>().data(), out);
  }

 private:
  void run(OpKernelContext* ctx, const Dims& d, const float* dh_out, const float* keep,
           const float* state[5], const float* c_prev, const T* w, const float* peep,
           float* dz);
};

template <>
void BackwardOp<float>::run(OpKernelContext* ctx, const Dims& d, const float* dh_out,
                            const float* keep, const float* state[5], const float* c_prev,
                            const float* w, const float* peep, float* dz) {
  backward<Fp32Panels>(ctx, d, dh_out, keep, state, c_prev, w, peep, dz);
}

#if defined(__AVX512BF16__)
template <>
void ForwardOp<bfloat16>::run(OpKernelContext* ctx, const Dims& d, const float* x_proj,
                              const float* keep, const bfloat16* w, const float* peep,
                              float* out[6]) {
  forward<Bf16Panels>(ctx, d, x_proj, keep, w, peep, out);
}

template <>
void BackwardOp<bfloat16>::run(OpKernelContext* ctx, const Dims& d, const float* dh_out,
                               const float* keep, const float* state[5], const float* c_prev,
                               const bfloat16* w, const float* peep, float* dz) {
  backward<Bf16Panels>(ctx, d, dh_out, keep, state, c_prev, w, peep, dz);
}
#define MTRNN_WEIGHT_TYPES "T: {float, bfloat16}"
#else
#define MTRNN_WEIGHT_TYPES "T: {float}"
#endif

tensorflow::Status same_as_input(tensorflow::shape_inference::InferenceContext* c, int outputs) {
  for (int k = 0; k < outputs; ++k) c->set_output(k, c->input(0));
  return tensorflow::OkStatus();
}

}  // namespace

REGISTER_OP("MtrnnLstmForward")
    .Attr(MTRNN_WEIGHT_TYPES)
    .Input("x_proj: float")
    .Input("keep: float")
    .Input("w: T")
    .Input("peep: float")
    .Input("steps: int32")
    .Output("h: float")
    .Output("c: float")
    .Output("g: float")
    .Output("i: float")
    .Output("f: float")
    .Output("o: float")
    .SetShapeFn([](tensorflow::shape_inference::InferenceContext* c) {
      tensorflow::shape_inference::ShapeHandle x = c->input(0), out;
      TF_RETURN_IF_ERROR(c->WithRank(x, 3, &x));
      TF_RETURN_IF_ERROR(
          c->ReplaceDim(x, 2, c->Dim(c->input(2), 0), &out));
      for (int k = 0; k < 6; ++k) c->set_output(k, out);
      return tensorflow::OkStatus();
    });

REGISTER_OP("MtrnnLstmBackward")
    .Attr(MTRNN_WEIGHT_TYPES)
    .Input("dh_out: float")
    .Input("keep: float")
    .Input("c: float")
    .Input("g: float")
    .Input("i: float")
    .Input("f: float")
    .Input("o: float")
    .Input("c_prev: float")
    .Input("w: T")
    .Input("peep: float")
    .Input("steps: int32")
    .Output("dz: float")
    .SetShapeFn([](tensorflow::shape_inference::InferenceContext* c) {
      tensorflow::shape_inference::ShapeHandle x = c->input(0), out;
      TF_RETURN_IF_ERROR(c->WithRank(x, 3, &x));
      TF_RETURN_IF_ERROR(c->ReplaceDim(x, 2, c->Dim(c->input(8), 1), &out));
      c->set_output(0, out);
      return tensorflow::OkStatus();
    });

REGISTER_OP("MtrnnWeightGradient")
    .Input("h_prev: float")
    .Input("dz: float")
    .Output("dw: float")
    .SetShapeFn([](tensorflow::shape_inference::InferenceContext* c) {
      tensorflow::shape_inference::ShapeHandle a, b;
      TF_RETURN_IF_ERROR(c->WithRank(c->input(0), 2, &a));
      TF_RETURN_IF_ERROR(c->WithRank(c->input(1), 2, &b));
      c->set_output(0, c->Matrix(c->Dim(a, 1), c->Dim(b, 1)));
      return tensorflow::OkStatus();
    });

REGISTER_KERNEL_BUILDER(
    Name("MtrnnLstmForward").Device(tensorflow::DEVICE_CPU).TypeConstraint<float>("T")
        .HostMemory("steps"),
    ForwardOp<float>);
REGISTER_KERNEL_BUILDER(
    Name("MtrnnLstmBackward").Device(tensorflow::DEVICE_CPU).TypeConstraint<float>("T")
        .HostMemory("steps"),
    BackwardOp<float>);
REGISTER_KERNEL_BUILDER(Name("MtrnnWeightGradient").Device(tensorflow::DEVICE_CPU),
                        WeightGradientOp);
#if defined(__AVX512BF16__)
REGISTER_KERNEL_BUILDER(
    Name("MtrnnLstmForward").Device(tensorflow::DEVICE_CPU).TypeConstraint<bfloat16>("T")
        .HostMemory("steps"),
    ForwardOp<bfloat16>);
REGISTER_KERNEL_BUILDER(
    Name("MtrnnLstmBackward").Device(tensorflow::DEVICE_CPU).TypeConstraint<bfloat16>("T")
        .HostMemory("steps"),
    BackwardOp<bfloat16>);
#endif

// The tracker's side of learned appearance: which bank a frame uses (RT), folding a batch into
// the model and publishing a bank into the free slot (worker or offline loop), the worker
// thread and the counters.
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <system_error>
#include <thread>

#include "sempose/rt/thread_room.hpp"
#include "tracker_impl.hpp"

namespace sempose::pose {

// RT: the bank this frame uses: the learned one published last, else the recorded one. A new
// one brings its noise floors (a smaller support lets noise reach higher scores).
const PatternBank& Tracker::Impl::frame_bank(std::uint8_t set) noexcept {
  if (!learned) return *banks[set];
  LearnedBanks& l = learned[set];
  const int k = l.published.load(std::memory_order_acquire);
  l.in_use.store(k, std::memory_order_release);
  const int seen = set * 4 + k;  // changes with the set or the slot
  if (seen != bank_seen) {
    bank_seen = seen;
    floor_scale_now = k < 0 ? 1.0f : l.floor_scale[k];
    use_noise_floors_of(set);
  }
  return k < 0 ? *banks[set] : *l.slot[k];
}

bool Tracker::Impl::maintain_appearance() {
  if (!observer) return false;
  // SEMPOSE_APPEARANCE_TRACE=1: one line per batch on stderr (what the model decided; not RT).
  static const bool trace_appearance = std::getenv("SEMPOSE_APPEARANCE_TRACE") != nullptr;
  // The model and the slots have one writer: a second caller (a worker thread and an offline
  // loop at once) returns at once instead of waiting.
  if (maintaining.test_and_set(std::memory_order_acquire)) return false;
  struct Release {
    std::atomic_flag& f;
    ~Release() { f.clear(std::memory_order_release); }
  } release{maintaining};
  const AppearanceStats* batch = observer->take();
  if (batch == nullptr) return false;
  const std::uint8_t set = batch->set;
  AppearanceDecision d = model->update(*batch);
  observer->give_back();
  if (trace_appearance)
    std::fprintf(stderr,
                 "appearance: set %u frames %d accepted %d support %.3f drift %.3f px%s%s | template %s (moved %.2f px, "
                 "align %.3f %.3f px %.3f deg, weight %.3f, noise x%.3f)%s%s\n",
                 set, d.frames, d.accepted ? 1 : 0, d.support_fraction, d.drift_px, d.why.empty() ? "" : ": ",
                 d.why.c_str(), d.template_updated ? "updated" : "kept", d.motion_px, d.align_dx, d.align_dy,
                 d.align_dphi_deg, d.template_weight, d.template_noise_factor, d.template_why.empty() ? "" : ": ",
                 d.template_why.c_str());
  if (!d.accepted) {
    appearance_rejected.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  LearnedBanks& l = learned[set];
  const int cur = l.published.load(std::memory_order_acquire);
  // The other slot is free once update() has picked up the current one.
  if (l.in_use.load(std::memory_order_acquire) != cur) {
    appearance_deferred.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const int next = cur == 0 ? 1 : 0;
  std::string why;
  // With tracker.appearance.refine_template, the copies are the refined template's (drift-
  // corrected, blended with the recorded pattern: appearance_model.cpp), else base's.
  const bool refined = !d.refined.empty();
  std::unique_ptr<const PatternBank> bank = PatternBank::with_support(
      *banks[set], d.support, why, refined ? d.refined.data() : nullptr, refined ? d.template_noise_factor : 1.0);
  if (!bank) {
    appearance_rejected.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  l.floor_scale[next] = static_cast<float>(std::sqrt(banks[set]->mean_support_count() / bank->mean_support_count()));
  l.slot[next] = std::move(bank);
  l.published.store(next, std::memory_order_release);
  appearance_accepted.fetch_add(1, std::memory_order_relaxed);
  appearance_support.store(d.support_fraction, std::memory_order_relaxed);
  if (d.template_updated) appearance_template_updates.fetch_add(1, std::memory_order_relaxed);
  appearance_template_weight.store(d.template_weight, std::memory_order_relaxed);
  return true;
}

bool Tracker::maintain_appearance() { return impl_->maintain_appearance(); }

rt::Status Tracker::start_appearance_worker() {
  Impl& t = *impl_;
  if (!t.observer || t.worker.joinable()) return rt::Status::success();
  try {
    t.worker = std::thread([&t] {
      const timespec period{0, 20'000'000};
      while (!t.worker_stop.load(std::memory_order_relaxed)) {
        t.maintain_appearance();
        nanosleep(&period, nullptr);
      }
    });
  } catch (const std::system_error& e) {
    std::string why = std::string("the learned appearance's worker thread (tracker.appearance.enabled) cannot be created (") +
                      e.what() + ")";
    if (e.code() == std::errc::resource_unavailable_try_again) why += std::string(": ") + rt::kThreadLimitHint;
    return rt::Status::failure(why);
  }
  return rt::Status::success();
}

Tracker::AppearanceStatus Tracker::appearance_status() const noexcept {
  const Impl& t = *impl_;
  AppearanceStatus s;
  s.accepted = t.appearance_accepted.load(std::memory_order_relaxed);
  s.rejected = t.appearance_rejected.load(std::memory_order_relaxed);
  s.deferred = t.appearance_deferred.load(std::memory_order_relaxed);
  s.support_fraction = t.appearance_support.load(std::memory_order_relaxed);
  s.template_updates = t.appearance_template_updates.load(std::memory_order_relaxed);
  s.template_weight = t.appearance_template_weight.load(std::memory_order_relaxed);
  return s;
}

}  // namespace sempose::pose

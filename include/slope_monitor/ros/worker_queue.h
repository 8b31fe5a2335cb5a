// Items handled one at a time, in the order they were pushed, by a worker
// thread of their own: a subscriber's callback only queues, so a fast replay
// loses nothing while the worker is busy (the hex matcher's sequence mode).
//
//   WorkerQueue<Input> queue([this](std::optional<Input> in) { ... },
//                            std::chrono::milliseconds(50));
//   queue.Push(input);  // from any thread
//
// The handler gets each item, and an empty optional whenever none came for
// `idle` (a live node's time-outs are polled there). The destructor stops the
// worker after the item being handled (items still queued are dropped).
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

namespace slope_monitor {
namespace ros_adapters {

template <typename T>
class WorkerQueue {
 public:
  WorkerQueue(std::function<void(std::optional<T>)> handle, std::chrono::milliseconds idle)
      : handle_(std::move(handle)), idle_(idle), worker_([this] { Run(); }) {}

  ~WorkerQueue() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

  WorkerQueue(const WorkerQueue&) = delete;
  WorkerQueue& operator=(const WorkerQueue&) = delete;

  void Push(T item) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      items_.push_back(std::move(item));
    }
    cv_.notify_all();
  }

 private:
  void Run() {
    while (true) {
      std::optional<T> next;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait_for(lock, idle_, [this] { return stop_ || !items_.empty(); });
        if (stop_) return;
        if (!items_.empty()) {
          next = std::move(items_.front());
          items_.pop_front();
        }
      }
      handle_(std::move(next));
    }
  }

  std::function<void(std::optional<T>)> handle_;
  std::chrono::milliseconds idle_;
  std::mutex mutex_;  // items_, stop_
  std::condition_variable cv_;
  std::deque<T> items_;
  bool stop_ = false;
  std::thread worker_;  // last: started once the members above exist
};

}  // namespace ros_adapters
}  // namespace slope_monitor

import { Navigate, Route, Routes } from "react-router-dom";
import { useAuth } from "./auth/AuthContext";
import { RequireRole } from "./auth/RequireRole";
import { homeFor } from "./lib/roles";
import { AlarmDetailPage } from "./nurse/AlarmDetailPage";
import { FatiguePage } from "./nurse/FatiguePage";
import { HandoverPage } from "./nurse/HandoverPage";
import { HistoryPage } from "./nurse/HistoryPage";
import { NurseBoard } from "./nurse/NurseBoard";
import { AgreementPage } from "./pages/annotator/AgreementPage";
import { LabelPage } from "./pages/annotator/LabelPage";
import { ReviewPage } from "./pages/annotator/ReviewPage";
import { VideosPage } from "./pages/annotator/VideosPage";
import { ComparePage } from "./pages/engineer/ComparePage";
import { EngineerLayout } from "./pages/engineer/EngineerLayout";
import { FleetPage } from "./pages/engineer/FleetPage";
import { JobsPage } from "./pages/engineer/JobsPage";
import { ModelPage } from "./pages/engineer/ModelPage";
import { RegistryPage } from "./pages/engineer/RegistryPage";
import { AdminPage } from "./pages/admin/AdminPage";
import { StoragePage } from "./pages/admin/StoragePage";
import { Layout } from "./pages/Layout";
import { LoginPage } from "./pages/LoginPage";
import { NotHerePage } from "./pages/NotHerePage";

export function App() {
  const { user } = useAuth();
  return (
    <Routes>
      <Route path="/" element={<Navigate to={user ? homeFor(user.role) : "/login"} replace />} />
      <Route path="/login" element={<LoginPage />} />
      <Route element={<Layout />}>
        <Route path="/annotate" element={<RequireRole section="annotate"><VideosPage /></RequireRole>} />
        <Route path="/annotate/videos/:videoId" element={<RequireRole section="annotate"><LabelPage /></RequireRole>} />
        <Route path="/annotate/review" element={<RequireRole section="annotate"><ReviewPage /></RequireRole>} />
        <Route path="/annotate/agreement" element={<RequireRole section="annotate"><AgreementPage /></RequireRole>} />
        <Route path="/nurse" element={<RequireRole section="nurse"><NurseBoard /></RequireRole>} />
        <Route path="/nurse/history" element={<RequireRole section="nurse"><HistoryPage /></RequireRole>} />
        <Route path="/nurse/handover" element={<RequireRole section="nurse"><HandoverPage /></RequireRole>} />
        <Route path="/nurse/fatigue" element={<RequireRole section="nurse"><FatiguePage /></RequireRole>} />
        <Route path="/nurse/alarms/:alarmId" element={<RequireRole section="nurse"><AlarmDetailPage /></RequireRole>} />
        <Route path="/admin" element={<RequireRole section="admin"><AdminPage /></RequireRole>} />
        <Route path="/admin/storage" element={<RequireRole section="admin"><StoragePage /></RequireRole>} />
        <Route path="/engineer" element={<RequireRole section="engineer"><EngineerLayout /></RequireRole>}>
          <Route index element={<RegistryPage />} />
          <Route path="models/:modelId" element={<ModelPage />} />
          <Route path="compare" element={<ComparePage />} />
          <Route path="fleet" element={<FleetPage />} />
          <Route path="jobs" element={<JobsPage />} />
        </Route>
        <Route path="*" element={user ? <NotHerePage kind="not-found" /> : <Navigate to="/login" replace />} />
      </Route>
    </Routes>
  );
}

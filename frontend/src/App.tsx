import { Navigate, Route, Routes } from "react-router-dom";
import { useAuth } from "./auth/AuthContext";
import { RequireRole } from "./auth/RequireRole";
import { homeFor } from "./lib/roles";
import { AlarmDetailPage } from "./nurse/AlarmDetailPage";
import { FatiguePage } from "./nurse/FatiguePage";
import { HistoryPage } from "./nurse/HistoryPage";
import { NurseBoard } from "./nurse/NurseBoard";
import { AnnotatePage } from "./pages/AnnotatePage";
import { EngineerPage } from "./pages/EngineerPage";
import { Layout } from "./pages/Layout";
import { LoginPage } from "./pages/LoginPage";

export function App() {
  const { user } = useAuth();
  return (
    <Routes>
      <Route path="/login" element={<LoginPage />} />
      <Route element={<Layout />}>
        <Route path="/annotate" element={<RequireRole section="annotate"><AnnotatePage /></RequireRole>} />
        <Route path="/nurse" element={<RequireRole section="nurse"><NurseBoard /></RequireRole>} />
        <Route path="/nurse/history" element={<RequireRole section="nurse"><HistoryPage /></RequireRole>} />
        <Route path="/nurse/fatigue" element={<RequireRole section="nurse"><FatiguePage /></RequireRole>} />
        <Route path="/nurse/alarms/:alarmId" element={<RequireRole section="nurse"><AlarmDetailPage /></RequireRole>} />
        <Route path="/engineer" element={<RequireRole section="engineer"><EngineerPage /></RequireRole>} />
      </Route>
      <Route path="*" element={<Navigate to={user ? homeFor(user.role) : "/login"} replace />} />
    </Routes>
  );
}
